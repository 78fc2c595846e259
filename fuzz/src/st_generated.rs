//! Structure-aware fuzzing of the Structured Text run time: the input's bytes choose a
//! well-typed program (declarations, assignments, IF, CASE, FOR, WHILE, arrays, timers,
//! counters, numeric and conversion functions, extreme literals), which must compile, and
//! which is then scanned. Unlike mutated text, nearly every input reaches the run time:
//! arithmetic at the ends of each type's range, conversions out of range, division by zero,
//! indices outside the bounds, loops the watchdog must stop.

use std::fmt::Write as _;
use std::sync::Arc;

use arbitrary::Unstructured;

/// The generated program's variables, by type.
const INTS: &[&str] = &["i1", "i2"];
const DINTS: &[&str] = &["d1", "d2", "d3"];
const LREALS: &[&str] = &["r1", "r2"];
const BOOLS: &[&str] = &["b1", "b2"];

const DECLARATIONS: &str = "PROGRAM fuzz
VAR
  i1, i2 : INT;
  d1, d2, d3 : DINT;
  k1, k2, k3, k4, k5 : DINT;
  r1, r2 : LREAL;
  b1, b2 : BOOL;
  a : ARRAY[0..7] OF DINT;
  t : TON;
  c : CTU;
  w : WORD;
  l : LINT;
  s : STRING;
END_VAR
";

pub fn run(data: &[u8]) {
    let mut u = Unstructured::new(data);
    let mut g = Generator {
        u: &mut u,
        out: String::from(DECLARATIONS),
        depth: 0,
        loops: 0,
    };
    for _ in 0..g.below(12) + 1 {
        g.statement();
    }
    g.out.push_str("END_PROGRAM\n");
    let program = match rtcnc_plc::compile(&g.out, "generated.st") {
        Ok(p) => p,
        // The compiler folds constant expressions and refuses one whose value is out of
        // its type or undefined, as it must: the only refusals a generated program may get.
        Err(e) if e.0.iter().all(|e| folded_constant(&e.message)) => return,
        Err(e) => panic!("a generated program must compile:\n{}\n{e}", g.out),
    };
    crate::st_text::scan(Arc::new(program), data);
}

fn folded_constant(message: &str) -> bool {
    [
        "does not fit",
        "overflow",
        "division by zero",
        "out of range",
        "outside",
    ]
    .iter()
    .any(|m| message.contains(m))
}

struct Generator<'a, 'b> {
    u: &'a mut Unstructured<'b>,
    out: String,
    depth: u32,
    /// FOR loops around the statement being generated.
    loops: u32,
}

impl Generator<'_, '_> {
    fn below(&mut self, n: u32) -> u32 {
        self.u.int_in_range(0..=n.saturating_sub(1)).unwrap_or(0)
    }

    fn pick<'s>(&mut self, from: &[&'s str]) -> &'s str {
        from[self.below(from.len() as u32) as usize]
    }

    fn statement(&mut self) {
        self.depth += 1;
        let nested = self.depth < 4;
        let choice = self.below(if nested { 14 } else { 9 });
        match choice {
            0 | 1 => {
                let v = self.pick(DINTS);
                let e = self.dint_any();
                let _ = writeln!(self.out, "{v} := {e};");
            }
            2 => {
                let v = self.pick(INTS);
                let e = self.int_any();
                let _ = writeln!(self.out, "{v} := {e};");
            }
            3 => {
                let v = self.pick(LREALS);
                let e = self.lreal_any();
                let _ = writeln!(self.out, "{v} := {e};");
            }
            4 => {
                let v = self.pick(BOOLS);
                let e = self.boolean();
                let _ = writeln!(self.out, "{v} := {e};");
            }
            5 => {
                let i = self.dint_any();
                let e = self.dint_any();
                let _ = writeln!(self.out, "a[{i}] := {e};");
            }
            6 => {
                let b = self.boolean();
                let ms = self.below(20);
                let _ = writeln!(self.out, "t(IN := {b}, PT := T#{ms}ms);");
            }
            7 => {
                let b = self.boolean();
                let pv = self.int_any();
                let _ = writeln!(self.out, "c(CU := {b}, R := b2, PV := {pv});");
            }
            8 => {
                let e = self.dint();
                let _ = writeln!(
                    self.out,
                    "l := DINT_TO_LINT({e}) * l + 1; w := DINT_TO_WORD({e}); s := DINT_TO_STRING({e});"
                );
            }
            9 => {
                let b = self.boolean();
                let _ = writeln!(self.out, "IF {b} THEN");
                self.block();
                self.out.push_str("ELSE\n");
                self.block();
                self.out.push_str("END_IF;\n");
            }
            10 => {
                let e = self.dint();
                let _ = writeln!(self.out, "CASE {e} OF");
                // Labels that cannot overlap: one below 10, a range above 20.
                let label = self.u.arbitrary::<i16>().unwrap_or(0).min(9);
                let _ = writeln!(self.out, "{label}:");
                self.block();
                let lo = self.below(5);
                let _ = writeln!(self.out, "{}..{}:", lo + 20, lo + 22);
                self.block();
                self.out.push_str("ELSE\n");
                self.block();
                self.out.push_str("END_CASE;\n");
            }
            11 => {
                let (from, to, by) = (self.dint_any(), self.dint_any(), self.dint_any());
                // A control variable of its own per nesting level (IEC forbids reusing an
                // enclosing loop's).
                self.loops += 1;
                let k = self.loops;
                let _ = writeln!(self.out, "FOR k{k} := {from} TO {to} BY {by} DO");
                self.block();
                self.out.push_str("END_FOR;\n");
                self.loops -= 1;
            }
            12 => {
                let b = self.boolean();
                let _ = writeln!(self.out, "WHILE {b} DO");
                self.block();
                self.out.push_str("END_WHILE;\n");
            }
            _ => {
                let b = self.boolean();
                self.out.push_str("REPEAT\n");
                self.block();
                let _ = writeln!(self.out, "UNTIL {b} END_REPEAT;");
            }
        }
        self.depth -= 1;
    }

    fn block(&mut self) {
        for _ in 0..self.below(3) + 1 {
            self.statement();
        }
    }

    fn literal_dint(&mut self) -> String {
        match self.below(6) {
            0 => "2147483647".into(),
            1 => "-2147483648".into(),
            2 => "0".into(),
            _ => (self.u.arbitrary::<i16>().unwrap_or(0) as i32).to_string(),
        }
    }

    fn dint(&mut self) -> String {
        if self.depth > 6 {
            return self.pick(DINTS).to_string();
        }
        self.depth += 1;
        let e = match self.below(14) {
            0..=3 => self.pick(DINTS).to_string(),
            4 | 5 => {
                let op = self.pick(&["+", "-", "*", "/", "MOD"]);
                format!("({} {op} {})", self.dint(), self.dint_any())
            }
            6 => format!("ABS(-({}))", self.dint()),
            7 => format!("LREAL_TO_DINT({})", self.lreal()),
            8 => format!("INT_TO_DINT({})", self.int()),
            9 => format!("a[{}]", self.dint()),
            10 => format!("LIMIT(-100, {}, 100)", self.dint()),
            11 => format!("MAX({}, {})", self.dint(), self.dint_any()),
            12 => format!("TRUNC({})", self.lreal()),
            _ => format!(
                "SEL({}, {}, {})",
                self.boolean(),
                self.dint(),
                self.dint_any()
            ),
        };
        self.depth -= 1;
        e
    }

    /// A DINT expression or a literal: the compiler folds an expression of constants only,
    /// so a literal appears where a variable's expression is beside it.
    fn dint_any(&mut self) -> String {
        if self.below(3) == 0 {
            self.literal_dint()
        } else {
            self.dint()
        }
    }

    fn int_any(&mut self) -> String {
        match self.below(5) {
            0 => "32767".into(),
            1 => "-32768".into(),
            2 => (self.u.arbitrary::<i8>().unwrap_or(0)).to_string(),
            _ => self.int(),
        }
    }

    fn lreal_any(&mut self) -> String {
        if self.below(3) == 0 {
            let literals = [
                "1.0E308",
                "-1.0E308",
                "0.0",
                "-0.0",
                "1.0E-308",
                "3.0E9",
                "-3.0E9",
                "2147483647.5",
                "-2147483648.5",
                "4.5",
            ];
            self.pick(&literals).to_string()
        } else {
            self.lreal()
        }
    }

    fn int(&mut self) -> String {
        if self.depth > 6 {
            return self.pick(INTS).to_string();
        }
        self.depth += 1;
        let e = match self.below(6) {
            0 | 1 => self.pick(INTS).to_string(),
            2 | 3 => {
                let op = self.pick(&["+", "-", "*", "/", "MOD"]);
                format!("({} {op} {})", self.int(), self.int_any())
            }
            4 => format!("DINT_TO_INT({})", self.dint()),
            _ => format!("LREAL_TO_INT({})", self.lreal()),
        };
        self.depth -= 1;
        e
    }

    fn lreal(&mut self) -> String {
        if self.depth > 6 {
            return self.pick(LREALS).to_string();
        }
        self.depth += 1;
        let e = match self.below(12) {
            0..=3 => self.pick(LREALS).to_string(),
            4 => {
                let op = self.pick(&["+", "-", "*", "/", "**"]);
                format!("({} {op} {})", self.lreal(), self.lreal_any())
            }
            5 => format!("SQRT({})", self.lreal()),
            6 => format!("LN({})", self.lreal()),
            7 => format!("EXP({})", self.lreal()),
            8 => format!("DINT_TO_LREAL({})", self.dint()),
            9 => format!("SIN({})", self.lreal()),
            10 => format!("EXPT({}, {})", self.lreal(), self.int_any()),
            _ => format!("TIME_TO_LREAL(t.ET)"),
        };
        self.depth -= 1;
        e
    }

    fn boolean(&mut self) -> String {
        if self.depth > 6 {
            return self.pick(BOOLS).to_string();
        }
        self.depth += 1;
        let e = match self.below(9) {
            0 => self.pick(&["TRUE", "FALSE"]).to_string(),
            1 | 2 => self.pick(BOOLS).to_string(),
            3 => {
                let op = self.pick(&["<", ">", "=", "<>", "<=", ">="]);
                format!("({} {op} {})", self.dint(), self.dint_any())
            }
            4 => {
                let op = self.pick(&["<", ">", "="]);
                format!("({} {op} {})", self.lreal(), self.lreal_any())
            }
            5 => {
                let op = self.pick(&["AND", "OR", "XOR"]);
                format!("({} {op} {})", self.boolean(), self.boolean())
            }
            6 => format!("NOT {}", self.boolean()),
            7 => "t.Q".into(),
            _ => "c.Q".into(),
        };
        self.depth -= 1;
        e
    }
}
