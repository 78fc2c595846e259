//! Bodies of rtcnc's coverage-guided fuzz targets (`fuzz_targets/*.rs` call them; see
//! docs/fuzzing.md). Each takes the fuzzer's bytes and must return without a panic, an
//! overflow (built with overflow checks) or a hang, whatever they are. A new target is a
//! module here, a three-line file in `fuzz_targets/`, a `[[bin]]` in Cargo.toml and,
//! optionally, seeds in `seeds/<target>/` and a dictionary `dict/<target>.dict`:
//! `scripts/fuzz.sh` runs every target it lists.

pub mod cli_args;
pub mod gcode;
pub mod machine_file;
pub mod st_generated;
pub mod st_text;

/// Runs one saved input of a target by name (for regression tests and reproductions).
pub fn run_target(target: &str, data: &[u8]) -> bool {
    match target {
        "cli_args" => cli_args::run(data),
        "gcode" => gcode::run(data),
        "machine_file" => machine_file::run(data),
        "st_generated" => st_generated::run(data),
        "st_text" => st_text::run(data),
        _ => return false,
    }
    true
}
