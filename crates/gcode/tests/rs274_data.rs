//! The programs of `tests/data/` against what LinuxCNC 2.9's `rs274` printed for them
//! (`NAME.canon`, `NAME.err`, made by `data/regenerate.sh`), run as `rtcnc check --canon`
//! runs them (cutter compensation after the interpreter): the G70-G72 lathe cycles, the
//! canned cycles in the three planes, G5.2/G5.3 NURBS blocks. Where rs274 is wrong on
//! purpose-built programs, the reference is rs274's own output for an equivalent program,
//! said so at each test.

use crate::common;
use std::path::{Path, PathBuf};

fn data(folder: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(folder)
}

#[test]
fn lathe_cycles_match_rs274() {
    common::all_match(&data("lathe_cycles"), true, &[], 45);
}

/// rs274 2.9 taps along the wrong axes in G18 and G19: its G74/G84 feed moves pass the
/// plane's coordinates in the XY order (interp_cycles.cc, convert_cycle_g74_g84, unchanged
/// in later releases). These are checked against the G17 cycle below instead.
const RS274_WRONG_TAPPING: [&str; 4] = ["g18_g74", "g18_g84", "g19_g74", "g19_g84"];

#[test]
fn canned_cycles_match_rs274_in_all_planes() {
    common::all_match(&data("canned_cycles"), true, &RS274_WRONG_TAPPING, 34);
}

/// Maps a G17 STRAIGHT_* line of rs274's onto the same move in another plane: the G17
/// program with its axis letters exchanged is the other plane's program, so its moves are
/// rs274's G17 moves with the coordinates exchanged the same way.
fn permute_move(line: &str, plane: u32) -> String {
    for name in ["STRAIGHT_TRAVERSE(", "STRAIGHT_FEED("] {
        if let Some(args) = line.strip_prefix(name) {
            let v: Vec<&str> = args.trim_end_matches(')').split(", ").collect();
            let (x, y, z) = (v[0], v[1], v[2]);
            // G18: the program's X Y Z are the G17 one's Y Z X; G19: Z X Y.
            let (px, py, pz) = if plane == 18 { (y, z, x) } else { (z, x, y) };
            let mut out = vec![px, py, pz];
            out.extend_from_slice(&v[3..]);
            return format!("{name}{})", out.join(", "));
        }
    }
    line.to_string()
}

#[test]
fn canned_cycles_in_g18_and_g19_are_the_g17_cycles_on_other_axes() {
    let dir = data("canned_cycles");
    let mut compared = 0;
    for cycle in [73, 74, 76, 81, 82, 83, 84, 85, 86, 87, 88, 89] {
        let g17 = dir.join(format!("g17_g{cycle}"));
        let rs274 = std::fs::read_to_string(g17.with_extension("canon")).unwrap();
        for plane in [18, 19] {
            if cycle == 76 {
                // Threading runs in X and Z whatever the plane.
                continue;
            }
            let program = dir.join(format!("g{plane}_g{cycle}.ngc"));
            let (ours, error) = common::run(&program, true);
            // The plane and the title comment name the plane; the rest is the same.
            let no_plane = |s: &str| -> String {
                s.lines()
                    .filter(|l| {
                        !l.starts_with("SELECT_PLANE(") && !l.starts_with("COMMENT(\"canned cycle")
                    })
                    .map(|l| format!("{l}\n"))
                    .collect()
            };
            let expected: String = no_plane(&rs274)
                .lines()
                .map(|l| permute_move(l, plane) + "\n")
                .collect();
            if let Err(e) = common::compare_lines(&no_plane(&ours), &expected) {
                panic!("G{cycle} in G{plane}: {e}; our error {error:?}");
            }
            assert_eq!(error, None, "G{cycle} in G{plane}");
            compared += 1;
        }
    }
    assert_eq!(compared, 22);
}

#[test]
fn nurbs_blocks_match_rs274() {
    common::all_match(&data("nurbs"), true, &[], 20);
}

/// Where rs274 2.9 goes wrong in a lathe cycle, `data/equivalents/NAME.rtcnc` is run here
/// and compared with rs274's output for `NAME.ngc`, a program that does the same without
/// the defect: g70_comp (G70 under G41/G42: rs274 computes the compensated entry from the
/// end of the profile it has just read, a stray rapid) is compared with the G70's moves
/// written out under the same compensation; g91_start (G91 G71 X Z: rs274 rapids to X and
/// Z taken as absolute) with the cycle started by an explicit G0. The title comment, the
/// notes of G90.1/G91.1 and repeated rapids to the same point are left out of both.
#[test]
fn lathe_cycles_where_rs274_is_wrong_match_equivalent_programs() {
    let dir = data("equivalents");
    let keep = |s: &str| -> String {
        let mut out = String::new();
        let mut last = "";
        for (n, l) in s.lines().enumerate() {
            let title = n == 6 && l.starts_with("COMMENT(");
            let ijk = l.starts_with("COMMENT(\"interpreter: IJK distance mode");
            let repeated = l == last && l.starts_with("STRAIGHT_TRAVERSE(");
            if !(title || ijk || repeated) {
                out.push_str(l);
                out.push('\n');
            }
            last = l;
        }
        out
    };
    let mut compared = 0;
    for reference in common::programs(&dir) {
        let ours = reference.with_extension("rtcnc");
        let expected = std::fs::read_to_string(reference.with_extension("canon")).unwrap();
        let (output, error) = common::run(&ours, true);
        assert_eq!(error, None, "{}", ours.display());
        if let Err(e) = common::compare_lines(&keep(&output), &keep(&expected)) {
            panic!("{}: {e}", ours.display());
        }
        compared += 1;
    }
    assert_eq!(compared, 2);
}
