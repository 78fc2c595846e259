//! What the command-line tests share.

/// Reads a running `rtcnc run`'s output in the background, and returns once it said that
/// the program runs (the signal handlers are in place by then); the thread returns all of
/// it.
pub fn stdout_once_running(child: &mut std::process::Child) -> std::thread::JoinHandle<String> {
    use std::io::BufRead as _;
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in std::io::BufReader::new(stdout).lines() {
            let line = line.unwrap();
            if line.starts_with("running ") {
                let _ = tx.send(());
            }
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    // A minute: a debug build on a loaded machine (it takes a second here).
    rx.recv_timeout(std::time::Duration::from_secs(60))
        .expect("rtcnc run says that the program runs");
    reader
}
