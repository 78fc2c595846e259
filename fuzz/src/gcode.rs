//! The G-code interpreter and the cutter compensation stage on any text: every canonical
//! command is formatted as rs274 prints it; errors must be located values. After the
//! program, its first line runs as MDI.

use rtcnc_gcode::compensation::Compensator;
use rtcnc_gcode::{Interpreter, Parameters, Settings, Tool, ToolTable};

/// Canonical commands taken from one input, at most (an endless loop ends here).
const MAX_COMMANDS: usize = 2_000;

pub fn run(data: &[u8]) {
    let mut tools = ToolTable::new();
    let mut t = Tool::new(1, 1);
    t.diameter = 3.0;
    t.offset.z = 10.0;
    tools.set(t);
    tools.set(Tool::new(2, 2));
    let settings = Settings {
        max_lines_without_output: 500,
        ..Settings::default()
    };
    let mut interp = Interpreter::new(settings, tools, Parameters::new());
    if interp.open_text("fuzz.ngc", data.to_vec()).is_err() {
        return;
    }
    let mut stage = Compensator::new();
    let mut text = Vec::new();
    let mut taken = 0;
    let mut errors = 0;
    while taken < MAX_COMMANDS {
        match interp.next_canon() {
            Some(Ok(c)) => {
                taken += 1;
                if stage.push(c).is_err() {
                    break;
                }
                while let Some(c) = stage.pop() {
                    text.clear();
                    c.write_rs274(&mut text, true);
                }
            }
            Some(Err(e)) => {
                assert!(!e.message.is_empty());
                let _ = e.to_string();
                errors += 1;
                if errors > 20 || !interp.resume_after_error() {
                    break;
                }
            }
            None => {
                stage.finish();
                while stage.pop().is_some() {}
                break;
            }
        }
    }
    let first = String::from_utf8_lossy(data.split(|&b| b == b'\n').next().unwrap_or(b""));
    if interp.execute_mdi(&first).is_ok() {
        for _ in (&mut interp).take(200) {}
    }
}
