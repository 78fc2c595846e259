//! Runs every program of `tests/corpus/` and compares the canonical commands with the ones
//! LinuxCNC 2.9's `rs274` printed for it (`NAME.canon`, made by `corpus/regenerate.sh`):
//! same lines, same words, numbers equal within 1e-4; and an error exactly where rs274
//! reported one (`NAME.err` not empty).

use crate::common;
#[test]
fn corpus_matches_rs274() {
    common::all_match(&common::corpus_dir(), false, &[], 60);
}
