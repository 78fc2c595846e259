//! Standard functions: typing and code for conversions (`*_TO_*`, `TRUNC`, BCD), numeric,
//! bit-string, selection, comparison and string functions.

use crate::ast::{Arg, BinOp, Name};
use crate::compiler::{Compiler, R, Scope, TE, Ty, builtin_expr, builtin_expr_wide, literal_elem};
use crate::error::{ErrorKind, Pos};
use crate::types::{Elem, IntKind, MAX_STRING_LEN, Type, as_unsigned, widens};
use crate::vm::{self, Builtin, Conv};

fn ik(e: Elem) -> IntKind {
    e.int_kind().unwrap_or(IntKind::I64)
}

/// Parameter names of the standard functions, for formal (named) calls.
fn param_names(f: &str) -> &'static [&'static str] {
    match f {
        "LIMIT" => &["MN", "IN", "MX"],
        "SEL" => &["G", "IN0", "IN1"],
        "MUX" => &["K"],
        "SHL" | "SHR" | "ROL" | "ROR" => &["IN", "N"],
        "LEFT" | "RIGHT" => &["IN", "L"],
        "MID" => &["IN", "L", "P"],
        "INSERT" => &["IN1", "IN2", "P"],
        "DELETE" => &["IN", "L", "P"],
        "REPLACE" => &["IN1", "IN2", "L", "P"],
        "FIND" => &["IN1", "IN2"],
        "EXPT" | "ATAN2" => &["IN1", "IN2"],
        _ => &["IN"],
    }
}

/// Puts named arguments in parameter order (`IN1`, `IN2`... for extensible functions).
fn ordered(c: &Compiler, fname: &str, args: &[Arg]) -> R<Vec<Arg>> {
    if args.iter().all(|a| matches!(a, Arg::Positional(_))) {
        return Ok(args.to_vec());
    }
    let names = param_names(fname);
    let mut slots: Vec<Option<Arg>> = Vec::new();
    for (i, a) in args.iter().enumerate() {
        match a {
            Arg::Positional(_) => {
                if slots.len() <= i {
                    slots.resize(i + 1, None);
                }
                slots[i] = Some(a.clone());
            }
            Arg::Input(n, e) => {
                let idx = names.iter().position(|p| *p == n.text).or_else(|| {
                    // IN1, IN2, ... of extensible functions; K then IN0.. for MUX.
                    let digits = n.text.strip_prefix("IN")?;
                    let k: usize = digits.parse().ok()?;
                    Some(if fname == "MUX" {
                        k + 1
                    } else {
                        k.checked_sub(1)?
                    })
                });
                let Some(idx) = idx else {
                    return Err(c.err_at(
                        n.pos,
                        ErrorKind::WrongArgument,
                        format!("{fname} has no parameter '{}'", n.text),
                    ));
                };
                if slots.len() <= idx {
                    slots.resize(idx + 1, None);
                }
                if slots[idx].is_some() {
                    return Err(c.err_at(
                        n.pos,
                        ErrorKind::WrongArgument,
                        format!("'{}' is given twice", n.text),
                    ));
                }
                slots[idx] = Some(Arg::Positional(e.clone()));
            }
            Arg::Output(n, _, _) => {
                return Err(c.err_at(
                    n.pos,
                    ErrorKind::WrongArgument,
                    format!("{fname} has no outputs"),
                ));
            }
        }
    }
    slots
        .into_iter()
        .enumerate()
        .map(|(i, s)| {
            s.ok_or_else(|| {
                c.err_at(
                    Pos::default(),
                    ErrorKind::WrongArgument,
                    format!("argument {} of {fname} is missing", i + 1),
                )
            })
        })
        .collect()
}

fn count(c: &Compiler, fname: &str, args: &[(TE, Pos)], min: usize, max: usize, pos: Pos) -> R<()> {
    if args.len() < min || args.len() > max {
        let want = if min == max {
            format!("{min}")
        } else if max == usize::MAX {
            format!("at least {min}")
        } else {
            format!("{min} to {max}")
        };
        return Err(c.err_at(
            pos,
            ErrorKind::WrongArgument,
            format!("{fname} takes {want} arguments, {} given", args.len()),
        ));
    }
    Ok(())
}

fn wrong(c: &Compiler, fname: &str, t: &Ty, pos: Pos, want: &str) -> crate::error::CompileError {
    c.err_at(
        pos,
        ErrorKind::WrongArgument,
        format!("{fname} needs {want}, not {}", c.type_label(t)),
    )
}

/// The real type an argument of a real function is computed in.
fn real_type(t: &Ty) -> Option<Elem> {
    match t {
        Ty::AnyInt(_) | Ty::AnyReal(_) => Some(Elem::LReal),
        Ty::T(t) => {
            let e = t.elem()?;
            if e.is_real() {
                Some(e)
            } else if widens(e, Elem::Real) {
                Some(Elem::Real)
            } else if widens(e, Elem::LReal) {
                Some(Elem::LReal)
            } else {
                None
            }
        }
    }
}

fn int_or_lit(t: &Ty) -> bool {
    match t {
        Ty::AnyInt(_) => true,
        Ty::T(t) => t.elem().is_some_and(|e| e.is_int()),
        Ty::AnyReal(_) => false,
    }
}

fn string_arg(c: &Compiler, fname: &str, a: (TE, Pos)) -> R<vm::Expr> {
    match &a.0.ty {
        Ty::T(t) if t.is_string() => Ok(Compiler::te_parts(a.0).1),
        t => Err(wrong(c, fname, t, a.1, "a STRING or WSTRING")),
    }
}

fn int_arg(c: &Compiler, fname: &str, a: (TE, Pos)) -> R<vm::Expr> {
    if !int_or_lit(&a.0.ty) {
        return Err(wrong(c, fname, &a.0.ty, a.1, "an integer"));
    }
    let t = match &a.0.ty {
        Ty::T(t) => t.clone(),
        _ => Type::Elem(Elem::LInt),
    };
    let e = t.elem().unwrap_or(Elem::LInt);
    let pos = a.1;
    let x = c.coerce_to(a.0, &t, pos)?;
    // Positions and lengths are evaluated as LINT.
    Ok(c.conversion(x, e, Elem::LInt))
}

pub(crate) fn call(
    c: &mut Compiler,
    name: &Name,
    args: &[Arg],
    sc: &mut Scope,
    pos: Pos,
    expect: Option<&Type>,
) -> R<TE> {
    let f = name.text.as_str();
    if let Some(te) = conversion(c, f, args, sc, pos)? {
        return Ok(te);
    }
    if let Some(te) = crate::dates::call(c, name, args, sc, pos)? {
        return Ok(te);
    }
    let known = [
        "ABS", "SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "ATAN2",
        "EXPT", "ADD", "SUB", "MUL", "DIV", "MOD", "AND", "OR", "XOR", "MOVE", "SHL", "SHR", "ROL",
        "ROR", "SEL", "MAX", "MIN", "LIMIT", "MUX", "GT", "GE", "EQ", "LE", "LT", "NE", "LEN",
        "LEFT", "RIGHT", "MID", "CONCAT", "INSERT", "DELETE", "REPLACE", "FIND", "TRUNC", "TIME",
    ];
    if !known.contains(&f) {
        return Err(c.err_at(
            name.pos,
            ErrorKind::Undeclared,
            format!("'{f}' is not a declared function"),
        ));
    }
    let args = ordered(c, f, args)?;
    let a = c.b_args(&args, sc, f)?;
    match f {
        "ABS" => abs(c, f, a, pos),
        "SQRT" | "LN" | "LOG" | "EXP" | "SIN" | "COS" | "TAN" | "ASIN" | "ACOS" | "ATAN" => {
            real_function(c, f, a, pos)
        }
        "ATAN2" | "EXPT" => real_pair(c, f, a, pos),
        "ADD" | "MUL" | "SUB" | "DIV" | "MOD" | "AND" | "OR" | "XOR" => arithmetic(c, f, a, pos),
        "MOVE" => move_value(c, f, a, pos),
        "SHL" | "SHR" | "ROL" | "ROR" => shift(c, f, a, pos),
        "SEL" => select(c, f, a, expect, pos),
        "MUX" => multiplex(c, f, a, expect, pos),
        "MAX" | "MIN" | "LIMIT" => extremum(c, f, a, expect, pos),
        "GT" | "GE" | "EQ" | "LE" | "LT" | "NE" => comparison(c, f, a, &args, sc, pos),
        "LEN" => length(c, f, a, pos),
        "FIND" => find(c, f, a, pos),
        "LEFT" | "RIGHT" | "MID" | "CONCAT" | "INSERT" | "DELETE" | "REPLACE" => {
            string_function(c, f, a, pos)
        }
        "TRUNC" => trunc(c, f, a, pos),
        "TIME" => {
            // CODESYS's `TIME()`: the time of the scan (the caller's PLC time).
            count(c, f, &a, 0, 0, pos)?;
            Ok(Compiler::te(
                Ty::T(Type::Elem(Elem::Time)),
                builtin_expr(Builtin::Now, Vec::new(), 0),
            ))
        }
        _ => Err(c.err_at(
            name.pos,
            ErrorKind::Undeclared,
            format!("'{f}' is not a declared function"),
        )),
    }
}

/// `ABS`: of a literal, a literal; else the same number type.
fn abs(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 1, 1, pos)?;
    match a[0].0.ty {
        Ty::AnyInt(v) => return Ok(Compiler::te(Ty::AnyInt(v.abs()), vm::Expr::Const(0))),
        Ty::AnyReal(v) => {
            return Ok(Compiler::te(Ty::AnyReal(v.abs()), vm::Expr::Const(0)));
        }
        Ty::T(_) => {}
    }
    let (t, p) = (a[0].0.ty.clone(), a[0].1);
    let ty = match &t {
        Ty::AnyInt(_) => Type::Elem(Elem::DInt),
        Ty::AnyReal(_) => Type::Elem(Elem::LReal),
        Ty::T(t) => t
            .elem()
            .filter(|e| e.is_num())
            .map(Type::Elem)
            .ok_or_else(|| wrong(c, f, &Ty::T(t.clone()), p, "a number"))?,
    };
    let e = ty.elem().unwrap_or(Elem::DInt);
    let x = c.coerce_to(a.remove(0).0, &ty, p)?;
    let b = if e.is_real() {
        Builtin::AbsR(e == Elem::Real)
    } else {
        Builtin::AbsI(ik(e))
    };
    Ok(Compiler::te(
        Ty::T(ty),
        c.folded(builtin_expr(b, vec![x], 0)),
    ))
}

/// `SQRT`, `LN`, `LOG`, `EXP` and the trigonometric functions of one real.
fn real_function(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 1, 1, pos)?;
    let literal = match a[0].0.ty {
        Ty::AnyInt(v) => Some(v as f64),
        Ty::AnyReal(v) => Some(v),
        Ty::T(_) => None,
    };
    if let Some(x) = literal {
        // A function of a literal is a literal (and takes the type it is used as).
        let v = match f {
            "SQRT" => x.sqrt(),
            "LN" => x.ln(),
            "LOG" => x.log10(),
            "EXP" => x.exp(),
            "SIN" => x.sin(),
            "COS" => x.cos(),
            "TAN" => x.tan(),
            "ASIN" => x.asin(),
            "ACOS" => x.acos(),
            _ => x.atan(),
        };
        return Ok(Compiler::te(Ty::AnyReal(v), vm::Expr::Const(0)));
    }
    let p = a[0].1;
    let e = real_type(&a[0].0.ty).ok_or_else(|| wrong(c, f, &a[0].0.ty, p, "a real"))?;
    let x = c.coerce_to(a.remove(0).0, &Type::Elem(e), p)?;
    let s = e == Elem::Real;
    let b = match f {
        "SQRT" => Builtin::Sqrt(s),
        "LN" => Builtin::Ln(s),
        "LOG" => Builtin::Log(s),
        "EXP" => Builtin::Exp(s),
        "SIN" => Builtin::Sin(s),
        "COS" => Builtin::Cos(s),
        "TAN" => Builtin::Tan(s),
        "ASIN" => Builtin::Asin(s),
        "ACOS" => Builtin::Acos(s),
        _ => Builtin::Atan(s),
    };
    Ok(Compiler::te(
        Ty::T(Type::Elem(e)),
        builtin_expr(b, vec![x], 0),
    ))
}

/// `ATAN2` and `EXPT` (a real to the power of any number).
fn real_pair(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 2, 2, pos)?;
    let lit = |t: &Ty| match t {
        Ty::AnyInt(v) => Some(*v as f64),
        Ty::AnyReal(v) => Some(*v),
        Ty::T(_) => None,
    };
    if let (Some(x), Some(y)) = (lit(&a[0].0.ty), lit(&a[1].0.ty)) {
        let v = if f == "EXPT" { x.powf(y) } else { x.atan2(y) };
        return Ok(Compiler::te(Ty::AnyReal(v), vm::Expr::Const(0)));
    }
    let p0 = a[0].1;
    let e = real_type(&a[0].0.ty).ok_or_else(|| wrong(c, f, &a[0].0.ty, p0, "a real"))?;
    let t = Type::Elem(e);
    let (x, y) = (a.remove(0), a.remove(0));
    let xe = c.coerce_to(x.0, &t, x.1)?;
    let ye = if f == "EXPT" {
        let ey = real_type(&y.0.ty).ok_or_else(|| wrong(c, f, &y.0.ty, y.1, "a number"))?;
        let ee = c.coerce_to(y.0, &Type::Elem(ey), y.1)?;
        c.conversion(ee, ey, Elem::LReal)
    } else {
        c.coerce_to(y.0, &t, y.1)?
    };
    let s = e == Elem::Real;
    if f == "EXPT" {
        let xl = c.conversion(xe, e, Elem::LReal);
        let r = vm::Expr::Bin(vm::Bin::PowR(s), Box::new((xl, ye)));
        Ok(Compiler::te(Ty::T(t), c.folded(r)))
    } else {
        Ok(Compiler::te(
            Ty::T(t),
            builtin_expr(Builtin::Atan2(s), vec![xe, ye], 0),
        ))
    }
}

/// `ADD`, `MUL`, `AND`, `OR`, `XOR` of two or more inputs; `SUB`, `DIV`, `MOD` of two.
fn arithmetic(c: &mut Compiler, f: &str, a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    let (min, max) = if matches!(f, "ADD" | "MUL" | "AND" | "OR" | "XOR") {
        (2, usize::MAX)
    } else {
        (2, 2)
    };
    count(c, f, &a, min, max, pos)?;
    let op = match f {
        "ADD" => BinOp::Add,
        "MUL" => BinOp::Mul,
        "SUB" => BinOp::Sub,
        "DIV" => BinOp::Div,
        "AND" => BinOp::And,
        "OR" => BinOp::Or,
        "XOR" => BinOp::Xor,
        _ => BinOp::Mod,
    };
    let mut it = a.into_iter();
    let Some((mut acc, _)) = it.next() else {
        return Err(c.err_at(pos, ErrorKind::WrongArgument, "arguments missing"));
    };
    for (x, p) in it {
        acc = c.binary_op(op, acc, x, p)?;
    }
    Ok(acc)
}

/// `MOVE`: its input.
fn move_value(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 1, 1, pos)?;
    Ok(a.remove(0).0)
}

/// `SHL`, `SHR`, `ROL`, `ROR` of a bit string; with CODESYS's conversions also of an
/// integer, shifted in its width as the unsigned integer of that width (zero fill), and
/// by a bit string's count.
fn shift(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 2, 2, pos)?;
    let (x, mut n) = (a.remove(0), a.remove(0));
    if c.codesys_conversions()
        && let Ty::T(t) = &n.0.ty
        && let Some(e) = t.elem().filter(|e| e.is_bit())
    {
        let (_, ne) = Compiler::te_parts(n.0);
        n.0 = Compiler::te(Ty::T(Type::Elem(as_unsigned(e))), ne);
    }
    // CODESYS 2.3 shifts a signed integer right arithmetically (the sign bit comes in);
    // SHL, ROL and ROR work on its bits as on the bit string of its width.
    if c.codesys_conversions()
        && f == "SHR"
        && let Ty::T(t) = &x.0.ty
        && let Some(e) = t.elem().filter(|e| e.is_int() && ik(*e).signed())
    {
        let ty = t.clone();
        let (_, xe) = Compiler::te_parts(x.0);
        let ne = int_arg(c, f, n)?;
        return Ok(Compiler::te(
            Ty::T(ty),
            builtin_expr(Builtin::Shr(ik(e)), vec![xe, ne], 0),
        ));
    }
    if c.codesys_conversions()
        && let Ty::T(t) = &x.0.ty
        && let Some(e) = t.elem().filter(|e| e.is_int())
    {
        let unsigned = match e {
            Elem::SInt | Elem::USInt => Elem::Byte,
            Elem::Int | Elem::UInt => Elem::Word,
            Elem::DInt | Elem::UDInt => Elem::DWord,
            _ => Elem::LWord,
        };
        let ty = t.clone();
        let (_, xe) = Compiler::te_parts(x.0);
        let bits = c.conversion(xe, e, unsigned);
        let shifted = shift(
            c,
            f,
            vec![(Compiler::te(Ty::T(Type::Elem(unsigned)), bits), x.1), n],
            pos,
        )?;
        let (_, se) = Compiler::te_parts(shifted);
        return Ok(Compiler::te(Ty::T(ty), c.conversion(se, unsigned, e)));
    }
    let ty = match &x.0.ty {
        Ty::T(t) if t.elem().is_some_and(|e| e.is_bit()) => t.clone(),
        Ty::AnyInt(_) => Type::Elem(Elem::DWord),
        t => {
            return Err(wrong(
                c,
                f,
                t,
                x.1,
                "a bit string (BYTE, WORD, DWORD, LWORD)",
            ));
        }
    };
    let k = ik(ty.elem().unwrap_or(Elem::DWord));
    let xe = c.coerce_to(x.0, &ty, x.1)?;
    let ne = int_arg(c, f, n)?;
    let b = match f {
        "SHL" => Builtin::Shl(k),
        "SHR" => Builtin::Shr(k),
        "ROL" => Builtin::Rol(k),
        _ => Builtin::Ror(k),
    };
    Ok(Compiler::te(Ty::T(ty), builtin_expr(b, vec![xe, ne], 0)))
}

/// `SEL`: one of two values by a BOOL.
fn select(
    c: &mut Compiler,
    f: &str,
    mut a: Vec<(TE, Pos)>,
    expect: Option<&Type>,
    pos: Pos,
) -> R<TE> {
    count(c, f, &a, 3, 3, pos)?;
    let g = a.remove(0);
    let ge = c
        .coerce_to(g.0, &Type::BOOL, g.1)
        .map_err(|_| c.err_at(g.1, ErrorKind::WrongArgument, "SEL needs a BOOL selector G"))?;
    let (ty, vals) = common_values(c, f, a, pos, expect)?;
    let mut v = vec![ge];
    v.extend(vals);
    Ok(Compiler::te(Ty::T(ty), builtin_expr(Builtin::Sel, v, 0)))
}

/// `MUX`: one of n values by an integer.
fn multiplex(
    c: &mut Compiler,
    f: &str,
    mut a: Vec<(TE, Pos)>,
    expect: Option<&Type>,
    pos: Pos,
) -> R<TE> {
    count(c, f, &a, 2, usize::MAX, pos)?;
    let k = a.remove(0);
    let ke = int_arg(c, f, k)?;
    let (ty, vals) = common_values(c, f, a, pos, expect)?;
    let mut v = vec![ke];
    v.extend(vals);
    Ok(Compiler::te(Ty::T(ty), builtin_expr(Builtin::Mux, v, 0)))
}

/// `MAX`, `MIN` of two or more values, `LIMIT` of three.
fn extremum(
    c: &mut Compiler,
    f: &str,
    a: Vec<(TE, Pos)>,
    expect: Option<&Type>,
    pos: Pos,
) -> R<TE> {
    if f == "LIMIT" {
        count(c, f, &a, 3, 3, pos)?;
    } else {
        count(c, f, &a, 2, usize::MAX, pos)?;
    }
    let (ty, vals) = common_values(c, f, a, pos, expect)?;
    let Some(e) = ty
        .elem()
        .filter(|e| e.is_num() || e.is_bit() || *e == Elem::Time)
    else {
        return Err(c.err_at(
            pos,
            ErrorKind::WrongArgument,
            format!("{f} needs numbers, bit strings or TIME"),
        ));
    };
    let b = match (f, e.is_real()) {
        ("MAX", true) => Builtin::MaxR,
        ("MIN", true) => Builtin::MinR,
        ("LIMIT", true) => Builtin::LimitR,
        ("MAX", false) => Builtin::MaxI(ik(e).signed()),
        ("MIN", false) => Builtin::MinI(ik(e).signed()),
        _ => Builtin::LimitI(ik(e).signed()),
    };
    Ok(Compiler::te(Ty::T(ty), builtin_expr(b, vals, 0)))
}

/// `GT`, `GE`, `EQ`, `LE`, `LT` of two or more inputs (chained), `NE` of two.
fn comparison(
    c: &mut Compiler,
    f: &str,
    mut a: Vec<(TE, Pos)>,
    args: &[Arg],
    sc: &mut Scope,
    pos: Pos,
) -> R<TE> {
    let max = if f == "NE" { 2 } else { usize::MAX };
    count(c, f, &a, 2, max, pos)?;
    let op = match f {
        "GT" => BinOp::Gt,
        "GE" => BinOp::Ge,
        "EQ" => BinOp::Eq,
        "LE" => BinOp::Le,
        "LT" => BinOp::Lt,
        _ => BinOp::Ne,
    };
    if a.len() == 2 {
        let (x, y) = (a.remove(0), a.remove(0));
        return c.binary_op(op, x.0, y.0, y.1);
    }
    // GT(a, b, c) = (a > b) AND (b > c): middle inputs are compiled into two
    // comparisons, so they may not call anything (no double side effects).
    for arg in &args[1..args.len() - 1] {
        if let Arg::Positional(e) = arg {
            if has_call(e) {
                return Err(c.err_at(
                    e.pos(),
                    ErrorKind::WrongArgument,
                    format!("{f}: middle inputs of a chained comparison may not call functions"),
                ));
            }
        }
    }
    let mut acc: Option<TE> = None;
    for i in 0..args.len() - 1 {
        let mut pair = c.b_args(&args[i..i + 2], sc, f)?;
        let (x, y) = (pair.remove(0), pair.remove(0));
        let cmp = c.binary_op(op, x.0, y.0, y.1)?;
        acc = Some(match acc {
            None => cmp,
            Some(prev) => c.binary_op(BinOp::And, prev, cmp, pos)?,
        });
    }
    acc.ok_or_else(|| c.err_at(pos, ErrorKind::WrongArgument, format!("{f} needs inputs")))
}

/// `LEN` of a string.
fn length(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 1, 1, pos)?;
    let wide = matches!(a[0].0.ty, Ty::T(Type::WString(_)));
    let s = string_arg(c, f, a.remove(0))?;
    let e = builtin_expr_wide(Builtin::Len, vec![s], 0, wide);
    Ok(Compiler::te(Ty::T(Type::Elem(Elem::Int)), e))
}

/// `FIND`: where a string occurs in another.
fn find(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 2, 2, pos)?;
    let wide = |x: &(TE, Pos)| matches!(x.0.ty, Ty::T(Type::WString(_)));
    if wide(&a[0]) != wide(&a[1]) {
        let want = if wide(&a[0]) { "a WSTRING" } else { "a STRING" };
        return Err(wrong(c, f, &a[1].0.ty, a[1].1, want));
    }
    let w = wide(&a[0]);
    let s1 = string_arg(c, f, a.remove(0))?;
    let s2 = string_arg(c, f, a.remove(0))?;
    Ok(Compiler::te(
        Ty::T(Type::Elem(Elem::Int)),
        builtin_expr_wide(Builtin::Find, vec![s1, s2], 0, w),
    ))
}

/// `LEFT`, `RIGHT`, `MID`, `CONCAT`, `INSERT`, `DELETE`, `REPLACE`: into a string temporary.
fn string_function(c: &mut Compiler, f: &str, a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    let (b, shape): (Builtin, &[bool]) = match f {
        "LEFT" => (Builtin::Left, &[true, false]),
        "RIGHT" => (Builtin::Right, &[true, false]),
        "MID" => (Builtin::Mid, &[true, false, false]),
        "INSERT" => (Builtin::Insert, &[true, true, false]),
        "DELETE" => (Builtin::Delete, &[true, false, false]),
        "REPLACE" => (Builtin::Replace, &[true, true, false, false]),
        _ => (Builtin::Concat, &[]),
    };
    // The result is a WSTRING when the first string is one; the others must match it.
    let wide = matches!(a.first(), Some((x, _)) if matches!(x.ty, Ty::T(Type::WString(_))));
    for ((x, p), is_str) in a.iter().zip(shape.iter().chain(std::iter::repeat(&true))) {
        let is_wide = matches!(x.ty, Ty::T(Type::WString(_)));
        if *is_str && matches!(&x.ty, Ty::T(t) if t.is_string()) && is_wide != wide {
            let want = if wide { "a WSTRING" } else { "a STRING" };
            return Err(wrong(c, f, &x.ty, *p, want));
        }
    }
    let mut vals = Vec::new();
    if f == "CONCAT" {
        count(c, f, &a, 2, usize::MAX, pos)?;
        for x in a {
            vals.push(string_arg(c, f, x)?);
        }
    } else {
        count(c, f, &a, shape.len(), shape.len(), pos)?;
        for (x, is_str) in a.into_iter().zip(shape.iter()) {
            vals.push(if *is_str {
                string_arg(c, f, x)?
            } else {
                int_arg(c, f, x)?
            });
        }
    }
    let dest = c.new_string_temp(pos, wide)?;
    let ty = if wide {
        Type::WString(MAX_STRING_LEN)
    } else {
        Type::String(MAX_STRING_LEN)
    };
    Ok(Compiler::te(
        Ty::T(ty),
        builtin_expr_wide(b, vals, dest, wide),
    ))
}

/// `TRUNC`: a real to DINT, towards zero.
fn trunc(c: &mut Compiler, f: &str, mut a: Vec<(TE, Pos)>, pos: Pos) -> R<TE> {
    count(c, f, &a, 1, 1, pos)?;
    let p = a[0].1;
    let e = real_type(&a[0].0.ty)
        .filter(|e| e.is_real())
        .ok_or_else(|| wrong(c, f, &a[0].0.ty, p, "a real"))?;
    let x = c.coerce_to(a.remove(0).0, &Type::Elem(e), p)?;
    Ok(Compiler::te(
        Ty::T(Type::Elem(Elem::DInt)),
        c.folded(vm::Expr::Conv(Conv::RealTrunc(IntKind::I32), Box::new(x))),
    ))
}

/// Brings value arguments of MAX/MIN/LIMIT/SEL/MUX to their common type.
fn common_values(
    c: &mut Compiler,
    f: &str,
    a: Vec<(TE, Pos)>,
    pos: Pos,
    expect: Option<&Type>,
) -> R<(Type, Vec<vm::Expr>)> {
    let mut ty: Option<Ty> = None;
    for (x, p) in &a {
        ty = Some(match ty {
            None => x.ty.clone(),
            Some(Ty::AnyInt(_)) if matches!(x.ty, Ty::AnyReal(_)) => x.ty.clone(),
            Some(t @ (Ty::AnyInt(_) | Ty::AnyReal(_)))
                if matches!(x.ty, Ty::AnyInt(_) | Ty::AnyReal(_)) =>
            {
                t
            }
            Some(t) => Ty::T(c.common_type(&t, &x.ty, *p).map_err(|mut e| {
                e.kind = ErrorKind::WrongArgument;
                e.message = format!("{f}: {}", e.message);
                e
            })?),
        });
    }
    let ty = match ty {
        Some(Ty::T(t)) => t,
        // Only literals: they take the type the result is used as, when it is numeric.
        Some(Ty::AnyInt(_)) => match expect.and_then(|t| t.elem()) {
            Some(e) if e.is_num() => Type::Elem(e),
            _ => Type::Elem(Elem::DInt),
        },
        Some(Ty::AnyReal(_)) => match expect.and_then(|t| t.elem()) {
            Some(e) if e.is_real() => Type::Elem(e),
            _ => Type::Elem(Elem::LReal),
        },
        None => {
            return Err(c.err_at(
                pos,
                ErrorKind::WrongArgument,
                format!("{f} needs arguments"),
            ));
        }
    };
    let ty = match ty {
        Type::Subrange(e, _, _) => Type::Elem(e),
        t => t,
    };
    if matches!(ty, Type::Array(_) | Type::Struct(_) | Type::Fb(_)) {
        return Err(c.err_at(
            pos,
            ErrorKind::WrongArgument,
            format!("{f} needs elementary values"),
        ));
    }
    let mut out = Vec::new();
    for (x, p) in a {
        out.push(c.coerce_to(x, &ty, p)?);
    }
    Ok((ty, out))
}

fn elem_or_string(n: &str) -> Option<Option<Elem>> {
    if n == "STRING" {
        Some(None)
    } else {
        Elem::from_name(n).map(Some)
    }
}

/// What a conversion function's name asks for.
enum ConversionKind {
    /// `X_TO_Y`, `TO_Y`, `ANY_TO_Y`.
    To,
    /// `X_TRUNC_Y`, `TRUNC_Y`: a real to an integer, towards zero.
    Trunc,
    /// `X_BCD_TO_Y`: a bit string read as BCD, to an integer.
    FromBcd,
    /// `X_TO_BCD_Y`: an integer to a bit string in BCD.
    ToBcd,
}

/// A conversion function's name taken apart: the source type (absent in `TO_Y`, which takes
/// the argument's own), the kind, the target type. `None` (for either type) stands for
/// STRING.
struct ConversionName {
    from: Option<Option<Elem>>,
    kind: ConversionKind,
    to: Option<Elem>,
}

impl ConversionName {
    /// Takes the name apart; `None` when it is not a conversion of known types.
    fn parse(f: &str) -> Option<ConversionName> {
        let (from, kind, to) = if let Some((a, b)) = f.split_once("_BCD_TO_") {
            (Some(a), ConversionKind::FromBcd, b)
        } else if let Some((a, b)) = f.split_once("_TO_BCD_") {
            (Some(a), ConversionKind::ToBcd, b)
        } else if let Some(b) = f.strip_prefix("TO_").or_else(|| f.strip_prefix("ANY_TO_")) {
            (None, ConversionKind::To, b)
        } else if let Some(b) = f.strip_prefix("TRUNC_") {
            (None, ConversionKind::Trunc, b)
        } else if let Some((a, b)) = f.split_once("_TRUNC_") {
            (Some(a), ConversionKind::Trunc, b)
        } else if let Some((a, b)) = f.split_once("_TO_") {
            (Some(a), ConversionKind::To, b)
        } else {
            return None;
        };
        let to = elem_or_string(to)?;
        let from = match from {
            Some(n) => Some(elem_or_string(n)?),
            None => None,
        };
        Some(ConversionName { from, kind, to })
    }
}

/// `X_TO_Y`, `TO_Y`, `X_TRUNC_Y`, `TRUNC_Y`, `X_BCD_TO_Y`, `X_TO_BCD_Y`; `None` when `f`
/// names no conversion.
fn conversion(c: &mut Compiler, f: &str, args: &[Arg], sc: &mut Scope, pos: Pos) -> R<Option<TE>> {
    if let Some(te) = wide_conversion(c, f, args, sc, pos)? {
        return Ok(Some(te));
    }
    let Some(name) = ConversionName::parse(f) else {
        return Ok(None);
    };
    let args = ordered(c, f, args)?;
    let mut a = c.b_args(&args, sc, f)?;
    count(c, f, &a, 1, 1, pos)?;
    let (x, p) = a.remove(0);
    if matches!(x.ty, Ty::T(Type::WString(_))) && name.to.is_none() && name.from.is_none() {
        // TO_STRING of a WSTRING.
        let xe = Compiler::te_parts(x).1;
        return Ok(Some(recode(c, xe, false, pos)?));
    }
    let (src, xe) = conversion_argument(c, f, x, p, name.from)?;
    let result_ty = match name.to {
        Some(e) => Type::Elem(e),
        None => Type::String(MAX_STRING_LEN),
    };
    let out = match (name.kind, src, name.to) {
        (ConversionKind::Trunc, Some(s), Some(t)) if s.is_real() && t.is_int() => {
            c.folded(vm::Expr::Conv(Conv::RealTrunc(ik(t)), Box::new(xe)))
        }
        (ConversionKind::Trunc, ..) => {
            return Err(c.err_at(
                pos,
                ErrorKind::WrongArgument,
                format!("{f} converts a real to an integer"),
            ));
        }
        (ConversionKind::FromBcd, Some(s), Some(t)) if s.is_bit() && t.is_int() => {
            c.folded(vm::Expr::Conv(
                Conv::Int(ik(t)),
                Box::new(vm::Expr::Conv(Conv::FromBcd, Box::new(xe))),
            ))
        }
        (ConversionKind::ToBcd, Some(s), Some(t)) if s.is_int() && t.is_bit() => {
            c.folded(vm::Expr::Conv(Conv::ToBcd(ik(t)), Box::new(xe)))
        }
        (ConversionKind::FromBcd | ConversionKind::ToBcd, ..) => {
            return Err(c.err_at(
                pos,
                ErrorKind::WrongArgument,
                format!("{f}: BCD conversions go between bit strings and integers"),
            ));
        }
        (ConversionKind::To, Some(s), Some(t)) => c.conversion(xe, s, t),
        (ConversionKind::To, Some(s), None) => to_string(c, s, xe, pos)?,
        (ConversionKind::To, None, Some(t)) => from_string(t, xe, false),
        (ConversionKind::To, None, None) => xe,
    };
    Ok(Some(Compiler::te(Ty::T(result_ty), out)))
}

/// A STRING or WSTRING at `xe` copied into a new string temporary as a WSTRING (`wide`)
/// or a STRING.
fn recode(c: &mut Compiler, xe: vm::Expr, wide: bool, pos: Pos) -> R<TE> {
    let dest = c.new_string_temp(pos, wide)?;
    let ty = if wide {
        Type::WString(MAX_STRING_LEN)
    } else {
        Type::String(MAX_STRING_LEN)
    };
    Ok(Compiler::te(
        Ty::T(ty),
        builtin_expr(Builtin::StrToStr(wide), vec![xe], dest),
    ))
}

/// Conversions from and to WSTRING (`WSTRING_TO_STRING`, `STRING_TO_WSTRING`,
/// `TO_WSTRING`, `INT_TO_WSTRING`, `WSTRING_TO_REAL`, ...): text goes through its STRING
/// form, as in CODESYS. `None` when `f` is no such conversion.
fn wide_conversion(
    c: &mut Compiler,
    f: &str,
    args: &[Arg],
    sc: &mut Scope,
    pos: Pos,
) -> R<Option<TE>> {
    let (from, to) = if let Some(b) = f.strip_prefix("TO_").or_else(|| f.strip_prefix("ANY_TO_")) {
        (None, b)
    } else if let Some((a, b)) = f.split_once("_TO_") {
        (Some(a), b)
    } else {
        return Ok(None);
    };
    if to != "WSTRING" && from != Some("WSTRING") {
        return Ok(None);
    }
    let target = match to {
        "WSTRING" => None,
        t => match elem_or_string(t) {
            Some(e) => Some(e),
            None => return Ok(None),
        },
    };
    let args = ordered(c, f, args)?;
    let mut a = c.b_args(&args, sc, f)?;
    count(c, f, &a, 1, 1, pos)?;
    let (x, p) = a.remove(0);
    if from == Some("WSTRING") {
        if !matches!(x.ty, Ty::T(Type::WString(_))) {
            return Err(wrong(c, f, &x.ty, p, "a WSTRING"));
        }
        let xe = Compiler::te_parts(x).1;
        return Ok(Some(match target {
            None => Compiler::te(Ty::T(Type::WString(MAX_STRING_LEN)), xe),
            Some(None) => recode(c, xe, false, pos)?,
            Some(Some(t)) => Compiler::te(Ty::T(Type::Elem(t)), from_string(t, xe, true)),
        }));
    }
    if from.is_none() && matches!(x.ty, Ty::T(Type::WString(_))) {
        return Ok(Some(Compiler::te(x.ty.clone(), Compiler::te_parts(x).1)));
    }
    let from = match from {
        Some(n) => match elem_or_string(n) {
            Some(e) => Some(e),
            None => return Ok(None),
        },
        None => None,
    };
    let (src, xe) = conversion_argument(c, f, x, p, from)?;
    let text = match src {
        Some(s) => to_string(c, s, xe, pos)?,
        None => xe,
    };
    Ok(Some(recode(c, text, true, pos)?))
}

/// The conversion's argument and the type it is converted from (`None`: STRING): the
/// declared source type, which the argument must widen to, or else the argument's own (an
/// enumeration's value as DINT, a literal as LINT or LREAL).
fn conversion_argument(
    c: &mut Compiler,
    f: &str,
    x: TE,
    p: Pos,
    from: Option<Option<Elem>>,
) -> R<(Option<Elem>, vm::Expr)> {
    match from {
        Some(Some(fe)) => {
            let xe = c.coerce_to(x, &Type::Elem(fe), p).map_err(|mut e| {
                e.kind = ErrorKind::WrongArgument;
                e.message = format!("{f}: {}", e.message);
                e
            })?;
            Ok((Some(fe), xe))
        }
        Some(None) => {
            if !matches!(x.ty, Ty::T(Type::String(_))) {
                return Err(wrong(c, f, &x.ty, p, "a STRING"));
            }
            Ok((None, Compiler::te_parts(x).1))
        }
        None => {
            let t = x.ty.clone();
            match &t {
                Ty::T(Type::String(_) | Type::WString(_)) => Ok((None, Compiler::te_parts(x).1)),
                Ty::T(Type::Enum(_)) => Ok((Some(Elem::DInt), Compiler::te_parts(x).1)),
                _ => {
                    let e = literal_elem(&t).or(match t {
                        Ty::AnyInt(_) => Some(Elem::LInt),
                        Ty::AnyReal(_) => Some(Elem::LReal),
                        _ => None,
                    });
                    let Some(e) = e else {
                        return Err(wrong(c, f, &t, p, "an elementary value"));
                    };
                    let xe = c.coerce_to(x, &Type::Elem(e), p)?;
                    Ok((Some(e), xe))
                }
            }
        }
    }
}

/// A value of elementary type `s` as text, into a new string temporary.
fn to_string(c: &mut Compiler, s: Elem, xe: vm::Expr, pos: Pos) -> R<vm::Expr> {
    let dest = c.new_string_temp(pos, false)?;
    let b = if s == Elem::Bool {
        Builtin::BoolToStr
    } else if s.is_real() {
        Builtin::RealToStr(s == Elem::Real)
    } else if s == Elem::Time {
        Builtin::TimeToStr
    } else if let Some(m) = crate::dates::Moment::of(s) {
        Builtin::MomentToStr(m)
    } else {
        Builtin::IntToStr(ik(s).signed())
    };
    Ok(builtin_expr(b, vec![xe], dest))
}

/// Text read as a value of elementary type `t`.
fn from_string(t: Elem, xe: vm::Expr, wide: bool) -> vm::Expr {
    let b = if t == Elem::Bool {
        Builtin::StrToBool
    } else if t.is_real() {
        Builtin::StrToReal(t == Elem::Real)
    } else if t == Elem::Time {
        Builtin::StrToTime
    } else if let Some(m) = crate::dates::Moment::of(t) {
        Builtin::StrToMoment(m)
    } else {
        Builtin::StrToInt(ik(t))
    };
    builtin_expr_wide(b, vec![xe], 0, wide)
}

/// True if the expression calls a function or method anywhere.
fn has_call(e: &crate::ast::Expr) -> bool {
    use crate::ast::{Expr, Part};
    match e {
        Expr::Call(..) | Expr::MethodCall(..) => true,
        Expr::Unary(_, a, _) | Expr::Typed(_, a) => has_call(a),
        Expr::Binary(_, a, b, _) => has_call(a) || has_call(b),
        Expr::Var(a) => a
            .parts
            .iter()
            .any(|p| matches!(p, Part::Index(ix, _) if ix.iter().any(has_call))),
        _ => false,
    }
}
