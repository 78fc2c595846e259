//! Generates a large ladder-like ST program: `rungs` statements, every fourth a TON call,
//! the others seal-in rungs over located inputs, internal coils and timer outputs, every
//! 25th driving a located output. Shared by the benchmark and a test.

use std::fmt::Write as _;

/// The program of `rungs` statements, as ST source text.
pub fn ladder_program(rungs: usize) -> String {
    let timers = rungs / 4;
    let coils = rungs - timers;
    let mut s = String::with_capacity(rungs * 80);
    s.push_str("PROGRAM Ladder\nVAR\n");
    for i in 0..64 {
        let _ = writeln!(s, "  in{i} AT %IX{}.{} : BOOL;", i / 8, i % 8);
        let _ = writeln!(s, "  out{i} AT %QX{}.{} : BOOL;", i / 8, i % 8);
    }
    for c in 0..coils {
        let _ = writeln!(s, "  c{c} : BOOL;");
    }
    for t in 0..timers.max(1) {
        let _ = writeln!(s, "  t{t} : TON;");
    }
    s.push_str("END_VAR\n");
    let mut c = 0usize;
    let mut t = 0usize;
    for r in 0..rungs {
        if r % 4 == 3 && t < timers {
            let src = c.saturating_sub(1);
            let pt = 20 + (t % 10) * 10;
            let _ = writeln!(s, "t{t}(IN := c{src}, PT := T#{pt}ms);");
            t += 1;
        } else if c < coils {
            let a = r % 64;
            let b = (r * 7 + 3) % 64;
            let tm = t.saturating_sub(1);
            if r % 25 == 24 {
                let _ = writeln!(
                    s,
                    "out{} := c{} AND NOT t{tm}.Q;",
                    r % 64,
                    c.saturating_sub(1)
                );
            } else {
                let _ = writeln!(s, "c{c} := (in{a} OR c{c}) AND NOT in{b} AND NOT t{tm}.Q;");
            }
            c += 1;
        }
    }
    s.push_str("END_PROGRAM\n");
    s
}
