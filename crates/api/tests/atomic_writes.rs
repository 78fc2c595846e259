//! 200 kill -9s of a process while it writes the tool table the way `PUT /api/setup/tools`
//! does (`files::write_atomically` of `ToolTable::to_text`): after each, the file parses and
//! is the old table or the new one, never a torn one. The writer is this test binary run
//! again as a child (`RTCNC_WRITER`), so that the kills are real process deaths.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use rtcnc_gcode::{Pose, Tool, ToolTable};

fn table(n: i32) -> ToolTable {
    let mut t = ToolTable::new();
    // A table big enough that a write takes a while: a torn one would be caught.
    for i in 1..=200 {
        let mut tool = Tool::new(i, i);
        tool.offset = Pose::from_array([
            0.0,
            0.0,
            -f64::from(i) - f64::from(n) / 1000.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ]);
        tool.diameter = f64::from(n);
        tool.comment = format!("write {n}");
        t.set(tool);
    }
    t
}

/// The writer: alternates two tables forever (until killed).
fn writer(path: &Path) -> ! {
    let mut n = 1;
    loop {
        rtcnc_api::files::write_atomically(path, table(n).to_text().as_bytes(), 0o644).unwrap();
        n = 3 - n;
    }
}

#[test]
fn kill_9_during_tool_table_writes_leaves_the_old_or_the_new_table() {
    if let Ok(path) = std::env::var("RTCNC_WRITER") {
        writer(Path::new(&path));
    }
    let dir = std::env::temp_dir().join(format!("rtcnc-kill-writes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("tools.tbl");
    rtcnc_api::files::write_atomically(&path, table(1).to_text().as_bytes(), 0o644).unwrap();
    let (one, two) = (table(1), table(2));
    let exe = std::env::current_exe().unwrap();
    let mut seen = [0usize; 2];
    for kill in 0..200u64 {
        let mut child = Command::new(&exe)
            .args([
                "--exact",
                "kill_9_during_tool_table_writes_leaves_the_old_or_the_new_table",
                "--nocapture",
            ])
            .env("RTCNC_WRITER", &path)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Kill at scattered moments of the write cycle.
        std::thread::sleep(Duration::from_micros(2_000 + (kill * 7919) % 20_000));
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let parsed = ToolTable::parse(&text).expect("the file parses after a kill");
        if parsed == one {
            seen[0] += 1;
        } else if parsed == two {
            seen[1] += 1;
        } else {
            panic!("after kill {kill}: neither the old nor the new table");
        }
    }
    // The kills fell in the middle of writing: both tables were found.
    assert!(seen[0] > 0 && seen[1] > 0, "{seen:?}");
    // The killed writers' temporary files are cleared away, the table stays.
    rtcnc_api::files::remove_stale_temporaries(&path);
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, ["tools.tbl"]);
    std::fs::remove_dir_all(&dir).unwrap();
}
