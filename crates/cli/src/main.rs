//! The `rtcnc` binary: everything is in the library (`rtcnc::main`).

fn main() -> std::process::ExitCode {
    rtcnc::main()
}
