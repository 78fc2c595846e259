//! The Structured Text compiler on any text and, when it compiles, the run time: scans
//! with the input image taken from the input's bytes, every variable read and formatted.
//! The dictionary (`dict/st_text.dict`) and the seeds (the shipped programs) keep most
//! mutations compiling, so that the run-time paths are reached.

use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{Runtime, RuntimeOptions, compile};

/// Statements and loop iterations one scan may run (small: an endless loop faults fast).
const WATCHDOG: u64 = 5_000;
const SCANS: u64 = 4;

pub fn run(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let Ok(program) = compile(&text, "fuzz.st") else {
        return;
    };
    scan(Arc::new(program), data);
}

/// Scans `program` a few times, inputs from `data`, and reads every variable back.
pub fn scan(program: Arc<rtcnc_plc::Program>, data: &[u8]) {
    let variables = program.variables();
    let mut plc = Runtime::with_options(
        program,
        RuntimeOptions {
            watchdog_budget: WATCHDOG,
            ..RuntimeOptions::default()
        },
    );
    for k in 0..SCANS {
        let image = plc.input_image_mut();
        for (i, byte) in image.iter_mut().enumerate() {
            *byte = data
                .get((i + k as usize * 7) % data.len().max(1))
                .copied()
                .unwrap_or(0);
        }
        if let Err(fault) = plc.scan(Duration::from_millis(k * 3)) {
            let _ = fault.to_string();
            break;
        }
    }
    for v in variables.iter().take(64) {
        if let Ok(var) = plc.resolve(&v.path) {
            let _ = plc.format(&var);
        }
    }
}
