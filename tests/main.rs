//! The end-to-end tests of the workspace, as one test binary (linking dominates a test
//! build's time): the real `tablec` executable, the runtime against the brute-force
//! reference, table files good and hostile, the C interface, allocation counting,
//! concurrent table swaps, robot programs compensated offline, the shipped data (the UR10 measurements read as they are) and
//! the documented figures.

mod common;

mod c_abi;
mod cli;
mod compat;
mod documented_commands;
mod eval;
mod hostile_csv;
mod hostile_inputs;
mod implausible_samples;
mod iso9283_path;
mod joint_terms;
mod latency_guard;
mod merged_samples;
mod no_alloc;
mod option_spelling;
mod options_first;
mod outputs;
mod plan_branches;
mod plan_rounds;
mod posture;
mod programs;
mod programs_fanuc;
mod programs_gcode;
mod programs_staubli;
mod programs_yaskawa;
mod residual_weight;
mod robot_mutation;
mod robots;
mod shipped_kr150_data;
mod table_files;
mod table_matches_reference;
mod table_mutation;
mod table_swap;
mod tcp_lever;
mod tracker;
mod ur10_measurements;
mod worked_example;
