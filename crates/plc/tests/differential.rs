//! Differential test of integer arithmetic: random expressions over every integer type are
//! compiled and run, and compared with a direct model of IEC semantics (two's complement
//! wrap-around in the type's width, division truncating toward zero, MOD with the sign of
//! the dividend, division by zero a fault). Typed literals exercise constant folding.

use std::sync::Arc;
use std::time::Duration;

use proptest::prelude::*;
use rtcnc_plc::{FaultKind, Runtime, Value, compile};

#[derive(Debug, Clone, Copy)]
struct IntType {
    name: &'static str,
    bits: u32,
    signed: bool,
}

const TYPES: [IntType; 8] = [
    IntType {
        name: "SINT",
        bits: 8,
        signed: true,
    },
    IntType {
        name: "INT",
        bits: 16,
        signed: true,
    },
    IntType {
        name: "DINT",
        bits: 32,
        signed: true,
    },
    IntType {
        name: "LINT",
        bits: 64,
        signed: true,
    },
    IntType {
        name: "USINT",
        bits: 8,
        signed: false,
    },
    IntType {
        name: "UINT",
        bits: 16,
        signed: false,
    },
    IntType {
        name: "UDINT",
        bits: 32,
        signed: false,
    },
    IntType {
        name: "ULINT",
        bits: 64,
        signed: false,
    },
];

impl IntType {
    fn wrap(self, v: i128) -> i128 {
        let m = 1i128 << self.bits;
        let u = v.rem_euclid(m);
        if self.signed && u >= m / 2 { u - m } else { u }
    }
}

#[derive(Debug, Clone)]
enum E {
    Var(usize),
    Lit(i128),
    Bin(char, Box<E>, Box<E>),
}

fn expr() -> impl Strategy<Value = E> {
    let leaf = prop_oneof![
        (0..3usize).prop_map(E::Var),
        any::<i64>().prop_map(|v| E::Lit(v as i128))
    ];
    leaf.prop_recursive(5, 24, 2, |inner| {
        (
            prop_oneof![Just('+'), Just('-'), Just('*'), Just('/'), Just('%')],
            inner.clone(),
            inner,
        )
            .prop_map(|(op, a, b)| E::Bin(op, Box::new(a), Box::new(b)))
    })
}

fn source(e: &E, t: IntType) -> String {
    match e {
        E::Var(i) => ["a", "b", "c"][*i].to_string(),
        E::Lit(v) => {
            let v = t.wrap(*v);
            if v < 0 {
                format!("{}#-{}", t.name, -v)
            } else {
                format!("{}#{v}", t.name)
            }
        }
        E::Bin(op, a, b) => {
            let o = if *op == '%' {
                "MOD".to_string()
            } else {
                op.to_string()
            };
            format!("({} {o} {})", source(a, t), source(b, t))
        }
    }
}

/// None: division by zero.
fn model(e: &E, t: IntType, vars: &[i128; 3]) -> Option<i128> {
    Some(match e {
        E::Var(i) => vars[*i],
        E::Lit(v) => t.wrap(*v),
        E::Bin(op, a, b) => {
            let x = model(a, t, vars)?;
            let y = model(b, t, vars)?;
            match op {
                '+' => t.wrap(x + y),
                '-' => t.wrap(x - y),
                '*' => t.wrap(x.wrapping_mul(y)),
                '/' if y == 0 => return None,
                '/' => t.wrap(x / y),
                _ if y == 0 => return None,
                _ => t.wrap(x % y),
            }
        }
    })
}

fn cases() -> u32 {
    std::env::var("PLC_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(if cfg!(debug_assertions) { 64 } else { 512 })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn integer_expressions_match_the_model(e in expr(), t in 0..TYPES.len(), vals in any::<[i64; 3]>()) {
        let t = TYPES[t];
        let vars = [t.wrap(vals[0] as i128), t.wrap(vals[1] as i128), t.wrap(vals[2] as i128)];
        let src = format!(
            "PROGRAM P VAR a : {n}; b : {n}; c : {n}; r : {n}; END_VAR r := {}; END_PROGRAM",
            source(&e, t),
            n = t.name
        );
        let expected = model(&e, t, &vars);
        let program = match compile(&src, "diff.st") {
            Ok(p) => p,
            Err(err) => {
                // Only a constant division by zero may be refused at compile time.
                prop_assert!(expected.is_none(), "{src}\n{err}");
                prop_assert!(err.to_string().contains("division by zero") || err.first().is_some_and(|e| e.code() == "invalid"), "{err}");
                return Ok(());
            }
        };
        let mut rt = Runtime::new(Arc::new(program));
        for (name, v) in ["a", "b", "c"].iter().zip(vars) {
            let r = rt.resolve(name).unwrap();
            let value = if t.signed { Value::Int(v as i64) } else { Value::UInt(v as u64) };
            rt.write(&r, &value).unwrap();
        }
        match (rt.scan(Duration::ZERO), expected) {
            (Ok(()), Some(want)) => {
                let got = match rt.read_name("r").unwrap() {
                    Value::Int(v) => v as i128,
                    Value::UInt(v) => v as i128,
                    v => panic!("{v:?}"),
                };
                prop_assert_eq!(got, want, "{}", src);
            }
            (Err(f), None) => prop_assert_eq!(f.kind, FaultKind::DivisionByZero),
            (got, want) => prop_assert!(false, "{src}: got {got:?}, model {want:?}"),
        }
    }
}

#[derive(Debug, Clone)]
enum F {
    Var(usize),
    Lit(f64),
    Bin(char, Box<F>, Box<F>),
}

fn real_expr() -> impl Strategy<Value = F> {
    let leaf = prop_oneof![
        (0..3usize).prop_map(F::Var),
        (-1e4f64..1e4).prop_map(F::Lit)
    ];
    leaf.prop_recursive(5, 24, 2, |inner| {
        (
            prop_oneof![Just('+'), Just('-'), Just('*'), Just('/')],
            inner.clone(),
            inner,
        )
            .prop_map(|(op, a, b)| F::Bin(op, Box::new(a), Box::new(b)))
    })
}

fn real_source(e: &F, ty: &str) -> String {
    match e {
        F::Var(i) => ["a", "b", "c"][*i].to_string(),
        F::Lit(v) => format!("{ty}#{v:e}"),
        F::Bin(op, a, b) => format!("({} {op} {})", real_source(a, ty), real_source(b, ty)),
    }
}

/// REAL arithmetic is single precision: every operation rounds to f32. None: x / 0.
fn real_model(e: &F, single: bool, vars: &[f64; 3]) -> Option<f64> {
    let round = |v: f64| if single { v as f32 as f64 } else { v };
    Some(match e {
        F::Var(i) => vars[*i],
        F::Lit(v) => round(*v),
        F::Bin(op, a, b) => {
            let x = real_model(a, single, vars)?;
            let y = real_model(b, single, vars)?;
            if single {
                let (x, y) = (x as f32, y as f32);
                (match op {
                    '+' => x + y,
                    '-' => x - y,
                    '*' => x * y,
                    _ if y == 0.0 => return None,
                    _ => x / y,
                }) as f64
            } else {
                match op {
                    '+' => x + y,
                    '-' => x - y,
                    '*' => x * y,
                    _ if y == 0.0 => return None,
                    _ => x / y,
                }
            }
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn real_expressions_match_the_model(e in real_expr(), single in any::<bool>(), vals in any::<[i32; 3]>()) {
        let ty = if single { "REAL" } else { "LREAL" };
        let round = |v: f64| if single { v as f32 as f64 } else { v };
        let vars = vals.map(|v| round(v as f64 / 7.0));
        let src = format!("PROGRAM P VAR a : {ty}; b : {ty}; c : {ty}; r : {ty}; END_VAR r := {}; END_PROGRAM", real_source(&e, ty));
        let expected = real_model(&e, single, &vars);
        let program = match compile(&src, "diff.st") {
            Ok(p) => p,
            Err(err) => {
                prop_assert!(expected.is_none(), "{src}\n{err}");
                return Ok(());
            }
        };
        let mut rt = Runtime::new(Arc::new(program));
        for (name, v) in ["a", "b", "c"].iter().zip(vars) {
            let r = rt.resolve(name).unwrap();
            rt.write(&r, &Value::Real(v)).unwrap();
        }
        match (rt.scan(Duration::ZERO), expected) {
            (Ok(()), Some(want)) => {
                let Value::Real(got) = rt.read_name("r").unwrap() else { panic!() };
                prop_assert!(got == want || (got.is_nan() && want.is_nan()), "{src}: got {got}, model {want}");
            }
            (Err(f), None) => prop_assert_eq!(f.kind, FaultKind::DivisionByZero),
            (got, want) => prop_assert!(false, "{src}: got {got:?}, model {want:?}"),
        }
    }
}
