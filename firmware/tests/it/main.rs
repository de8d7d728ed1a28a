//! The integration tests of `firmware`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod board_app;
mod board_io;
mod estimation;
mod protocol;
mod protocol_doc;
mod protocol_gaps;
mod safety;
mod uptime;
mod viscoelastic;
