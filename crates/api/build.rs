//! The web HMI's built bundle (web/dist, committed) is embedded with include_dir: the API
//! server is rebuilt when it changes.
fn main() {
    println!("cargo:rerun-if-changed=../../web/dist");
}
