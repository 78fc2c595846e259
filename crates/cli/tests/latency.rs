//! Smoke run of `rtcnc latency` (the built binary) and its argument errors.

use std::process::Command;

fn rtcnc() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rtcnc"))
}

#[test]
fn a_one_second_run_reports_statistics_a_plot_and_a_trace() {
    let dir = std::env::temp_dir().join(format!("rtcnc-latency-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let svg = dir.join("latency.svg");
    let trace = dir.join("trace.json");
    let out = rtcnc()
        .args([
            "latency",
            "--period",
            "1ms",
            "--duration",
            "1s",
            "--quiet",
            "--svg",
        ])
        .arg(&svg)
        .arg("--trace")
        .arg(&trace)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let line = stdout
        .lines()
        .find(|l| l.starts_with("latency (us): samples "))
        .expect("summary line");
    let samples: u64 = line.split_whitespace().nth(3).unwrap().parse().unwrap();
    assert!(stdout.contains("histogram"), "{stdout}");

    let plot = std::fs::read_to_string(&svg).unwrap();
    assert!(plot.starts_with("<svg") && plot.trim_end().ends_with("</svg>"));

    assert_eq!(samples, 1000, "1 s at 1 ms: {line}");

    // A complete event per period in the trace (the thread may run a period or two more
    // while it is being stopped).
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&trace).unwrap()).unwrap();
    let spans = json["traceEvents"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["ph"] == "X" && e["name"] == "measure")
        .count() as u64;
    assert!(spans >= samples, "{spans} spans for {samples} samples");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_arguments_are_refused_clearly() {
    for (args, message) in [
        (vec!["--period", "0"], "'0' must be greater than zero"),
        (vec!["--period=-1ms"], "'-1ms' must be greater than zero"),
        (vec!["--duration", "ten"], "'ten' is not a duration"),
        (vec!["--priority", "0"], "0 is not in 1..=99"),
    ] {
        let out = rtcnc().arg("latency").args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
}
