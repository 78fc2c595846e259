//! Every integration test of this crate but those that need a process of their own (see
//! Cargo.toml), as one test binary: one link instead of one per file.

mod common;
#[path = "support/line_programs.rs"]
mod line_programs;
#[path = "support/long_path_program.rs"]
mod long_path_program;
#[path = "support/spline_programs.rs"]
mod spline_programs;

mod arc_blends;
mod blend_policy;
mod compressor;
mod control;
mod curves;
mod errors;
mod head_kinematics;
mod jerk_above_the_period;
mod long_paths;
mod move_end;
mod online_changes;
mod otg_analytic;
mod otg_properties;
mod otg_ruckig_rest_to_rest;
mod otg_ruckig_state_to_state;
mod otg_straight;
mod otg_sync;
mod otg_velocity_sync;
mod paths;
mod prepared;
mod quick_stop_early_in_a_rapid;
mod random;
mod servo_periods;
mod spiral_arcs;
mod spline_blends;
mod splines;
mod splines_random;
mod stress_cases;
mod table_kinematics;
mod unemit;
