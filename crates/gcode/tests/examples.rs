//! The example programs shipped in `examples/gcode/` interpret without errors (their
//! canonical output was compared with rs274 when they were written).

use std::path::Path;

use rtcnc_gcode::{Interpreter, Parameters, Settings, ToolTable};

#[test]
fn example_programs_run_clean() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/gcode");
    let tools = ToolTable::load(&dir.join("tools.tbl")).unwrap();
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "ngc") {
            continue;
        }
        let mut interp = Interpreter::new(Settings::default(), tools.clone(), Parameters::new());
        interp.open(&path).unwrap();
        let mut ended = false;
        for c in &mut interp {
            let c = c.unwrap_or_else(|e| panic!("{e}"));
            ended |= c.command == rtcnc_gcode::CanonCommand::ProgramEnd;
        }
        assert!(ended, "{} does not reach its end", path.display());
        count += 1;
    }
    assert!(count >= 4);
}
