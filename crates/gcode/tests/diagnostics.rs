//! Every error is reported once, at its own line: a line too long, an unreadable file, an
//! error inside a loop; and only loops count towards the endless-loop limit.

use rtcnc_gcode::{GcodeError, Interpreter, Parameters, Settings, ToolTable};

/// Every error of `text` as `rtcnc check` collects them (resuming after each).
fn collect(text: &str, settings: Settings) -> (Vec<GcodeError>, usize) {
    let mut interp = Interpreter::new(settings, ToolTable::new(), Parameters::new());
    interp.open_text("t.ngc", text.as_bytes()).unwrap();
    let mut errors = Vec::new();
    let mut commands = 0;
    while errors.len() < 100 {
        match interp.next_canon() {
            Some(Ok(_)) => commands += 1,
            Some(Err(e)) => {
                errors.push(e);
                if !interp.resume_after_error() {
                    break;
                }
            }
            None => break,
        }
    }
    (errors, commands)
}

#[test]
fn a_line_too_long_is_one_error_at_its_own_line() {
    let text = format!(
        "G21 G90\nG1 X1 F100\n({})\nG1 X2 Y\nG1 X3\nG1 X4 Q Q\nM2\n",
        "a".repeat(100_000)
    );
    let (errors, _) = collect(&text, Settings::default());
    let lines: Vec<(u32, &str)> = errors
        .iter()
        .map(|e| (e.line, e.message.as_str()))
        .collect();
    assert_eq!(lines.len(), 3, "{lines:?}");
    assert_eq!(lines[0].0, 3);
    assert!(lines[0].1.starts_with("line too long"), "{lines:?}");
    // The lines after it keep their numbers.
    assert_eq!(lines[1].0, 4);
    assert_eq!(lines[2].0, 6);
}

#[test]
fn an_unreadable_program_is_one_error() {
    let dir = std::env::temp_dir().join(format!("rtcnc-gcode-dir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut interp = Interpreter::new(Settings::default(), ToolTable::new(), Parameters::new());
    // Opening a folder succeeds on Linux; reading it fails.
    if interp.open(&dir).is_err() {
        return;
    }
    let mut count = 0;
    while let Some(item) = interp.next_canon() {
        if item.is_err() {
            count += 1;
            if !interp.resume_after_error() {
                break;
            }
        }
        assert!(count < 100);
    }
    assert_eq!(count, 1);
}

#[test]
fn an_error_inside_a_loop_is_reported_once() {
    let (errors, _) = collect(
        "o100 while [1]\nG1 X1 Y\no100 endwhile\nM2\n",
        Settings::default(),
    );
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(errors[0].line, 2);
}

#[test]
fn only_loops_count_towards_the_endless_loop_limit() {
    let settings = || Settings {
        max_lines_without_output: 1_000,
        ..Settings::default()
    };
    // Ten times the limit in plain assignments, read straight through: no error.
    let mut text = String::from("G21\n");
    for i in 0..10_000 {
        text.push_str(&format!("#1 = {i}\n"));
    }
    text.push_str("G0 X#1\nM2\n");
    let (errors, commands) = collect(&text, settings());
    assert!(errors.is_empty(), "{errors:?}");
    assert!(commands > 0);
    // A loop that issues nothing is stopped, once.
    let (errors, _) = collect(
        "#1 = 0\no1 while [1]\n#1 = [#1 + 1]\no1 endwhile\nM2\n",
        settings(),
    );
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].message.contains("endless loop"), "{errors:?}");
}
