//! The integration tests of `host-tools`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod absurd_values;
mod child_processes;
mod cli_bad_input;
mod cli_board_messages;
mod cli_console;
mod cli_long_runs;
mod cli_messages;
mod cli_real_files;
mod cli_results;
mod cli_sim;
mod common;
mod console_excite;
mod contour_cli;
mod dlo_cli;
mod excite_stops;
mod hil_qemu_cli;
mod identify_cli;
mod long_run_memory;
mod long_searches;
mod probe;
mod rheology_cli;
mod sizes;
mod tetmsd_cli;
mod tissue_cli;
mod visco_cli;
mod writers_check_finite;
