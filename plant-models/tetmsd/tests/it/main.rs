//! The integration tests of `plant-tetmsd`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod packet_doc;
mod path_figures;
