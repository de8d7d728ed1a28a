//! The integration tests of `plant-dlo`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod campaign;
mod elastica;
mod elastica_ref;
mod rope;
mod rope_campaign;
mod splitmix;
