//! Machine files: any text through the TOML parser and the validation; an accepted file
//! builds the simulated machine, its servo loops and (without files on disk to read) the
//! whole kernel, as `rtcnc sim` would.

use rtcnc_kernel::{Kernel, KernelOptions, MachineConfig};

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let config = match MachineConfig::parse(text, "fuzz.toml") {
        Ok(c) => c,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    let _ = config.servo_period();
    let _ = config.axis_plan();
    // A PLC program or persistent files would be read from disk: not here.
    if config.plc.is_some()
        || config.files.parameters.is_some()
        || config.files.tool_table.is_some()
        || config.files.plc_retain.is_some()
    {
        return;
    }
    let _ = Kernel::build(
        &config,
        KernelOptions {
            trace_capacity: Some(16),
            ..KernelOptions::default()
        },
    );
}
