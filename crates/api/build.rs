// The web HMI's built bundle (web/dist, committed) is embedded with include_dir: rebuild
// this crate when it changes.
fn main() {
    println!("cargo:rerun-if-changed=../../web/dist");
}
