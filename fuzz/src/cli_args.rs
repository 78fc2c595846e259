//! The command line's argument grammar and value checks: the input's bytes split at NUL
//! or newline into arguments after `rtcnc`; parsing must end in arguments or a usage error.

use clap::Parser as _;

pub fn run(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let args = std::iter::once("rtcnc").chain(text.split(['\0', '\n']));
    match rtcnc::Cli::try_parse_from(args) {
        Ok(cli) => {
            let _ = format!("{cli:?}");
        }
        Err(e) => {
            let _ = e.render().to_string();
        }
    }
}
