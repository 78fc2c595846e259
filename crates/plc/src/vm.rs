//! The executable form of a compiled program and its interpreter.
//!
//! The compiler resolves every name to a byte address and every operator to a typed
//! operation, so a scan walks a tree of `Stmt` and `Expr` nodes over one byte image
//! (laid out as CODESYS lays it out, [`crate::types`]) without look-ups and without heap
//! allocation. Values are loaded into 64-bit registers ([`Repr`]) and computed there. Faults set `Vm::fault` and drop the statement
//! budget to zero; every statement boundary checks the budget, so a fault or an exhausted
//! watchdog budget stops the scan at the statement that caused it.

use crate::error::FaultKind;
use crate::stdfb::StdFb;
use crate::strings;
use crate::types::{IntKind, Repr};

/// Lowest address a pointer may reach: the first 8 bytes are never a variable, so a null
/// pointer's access lands there harmlessly while its fault stops the statement.
pub(crate) const FIRST_ADDRESS: usize = 8;

/// Base of a byte address: absolute, or relative to the running FB instance.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Base {
    Abs(u32),
    Rel(u32),
}

/// A storage location.
#[derive(Debug)]
pub(crate) enum Place {
    Abs(u32),
    Rel(u32),
    Dyn(Box<DynPlace>),
}

/// A location computed at run time: array indexing and/or a VAR_IN_OUT reference.
#[derive(Debug)]
pub(crate) struct DynPlace {
    pub base: Base,
    /// The base holds the address (VAR_IN_OUT parameter, pointer, reference).
    pub indirect: bool,
    pub offset: u32,
    pub steps: Box<[IndexStep]>,
    /// The base is itself at a computed place (a pointer or reference reached through an
    /// index or another pointer); `indirect` is then set.
    pub inner: Option<Box<DynPlace>>,
    /// Bytes of what is accessed, for the bounds check of an access through an address.
    pub span: u32,
}

#[derive(Debug)]
pub(crate) struct IndexStep {
    pub index: Expr,
    pub low: i64,
    pub len: u64,
    pub stride: u32,
}

// `repr(u8)` on the enums the interpreter dispatches on (operators, expressions,
// statements): a tag byte of its own, so the dispatch is one jump on it, where the
// niche-packed default layout needs up to a dozen instructions to find the variant.
#[derive(Debug, Clone, Copy)]
#[repr(u8)]
pub(crate) enum Un {
    NegI(IntKind),
    NegR(bool),
    NotBool,
    NotBits(IntKind),
    /// Reads bit n of an integer.
    Bit(u8),
}

#[derive(Debug, Clone, Copy)]
#[repr(u8)]
pub(crate) enum Bin {
    AddI(IntKind),
    SubI(IntKind),
    MulI(IntKind),
    DivI(IntKind),
    ModI(IntKind),
    /// Real arithmetic; the flag says REAL (round to f32) rather than LREAL.
    AddR(bool),
    SubR(bool),
    MulR(bool),
    DivR(bool),
    PowR(bool),
    And,
    Or,
    Xor,
    Eq,
    Ne,
    /// Integer order; the flag says signed.
    Lt(bool),
    Le(bool),
    Gt(bool),
    Ge(bool),
    EqR,
    NeR,
    LtR,
    LeR,
    GtR,
    GeR,
    /// String comparisons on string addresses (ordering, equal too, WSTRING).
    CmpS(std::cmp::Ordering, bool, bool),
    /// TIME * integer (the flag says the integer is signed), TIME / integer.
    MulTimeI,
    DivTimeI,
    MulTimeR,
    DivTimeR,
}

/// Conversions between register encodings.
#[derive(Debug, Clone, Copy)]
#[repr(u8)]
pub(crate) enum Conv {
    /// Integer to integer: wrap to the target width.
    Int(IntKind),
    /// Integer (signed flag) to real (REAL flag).
    IntToReal {
        signed: bool,
        f32: bool,
    },
    /// Real to integer, rounding half to even (IEC 60559).
    RealToInt(IntKind),
    /// Real to integer toward zero (TRUNC).
    RealTrunc(IntKind),
    /// LREAL to REAL.
    ToF32,
    /// Anything to BOOL: non-zero.
    IntToBool,
    RealToBool,
    /// TIME (ns) to milliseconds and back.
    NsToMs,
    MsToNs,
    RealMsToNs,
    NsToRealMs(bool),
    /// Binary-coded decimal.
    ToBcd(IntKind),
    FromBcd,
    /// DATE and DATE_AND_TIME (ns) to seconds and back.
    NsToS,
    SToNs,
    /// DATE_AND_TIME to its DATE (midnight) and to its TIME_OF_DAY.
    DayFloor,
    DayRem,
}

/// Built-in functions, chosen by type at compile time.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Builtin {
    AbsI(IntKind),
    AbsR(bool),
    Sqrt(bool),
    Ln(bool),
    Log(bool),
    Exp(bool),
    Sin(bool),
    Cos(bool),
    Tan(bool),
    Asin(bool),
    Acos(bool),
    Atan(bool),
    Atan2(bool),
    Shl(IntKind),
    Shr(IntKind),
    Rol(IntKind),
    Ror(IntKind),
    Sel,
    /// CODESYS's `TIME()`: the scan's PLC time.
    Now,
    Mux,
    MaxI(bool),
    MinI(bool),
    LimitI(bool),
    MaxR,
    MinR,
    LimitR,
    Len,
    Left,
    Right,
    Mid,
    Concat,
    Insert,
    Delete,
    Replace,
    Find,
    IntToStr(bool),
    RealToStr(bool),
    TimeToStr,
    BoolToStr,
    StrToInt(IntKind),
    StrToReal(bool),
    StrToBool,
    StrToTime,
    /// STRING to WSTRING (`true`) or WSTRING to STRING (`false`).
    StrToStr(bool),
    ConcatDate,
    ConcatTod,
    ConcatDt,
    DayOfWeek,
    MomentToStr(crate::dates::Moment),
    StrToMoment(crate::dates::Moment),
}

#[derive(Debug)]
#[repr(u8)]
pub(crate) enum Expr {
    Const(u64),
    LoadAbs(u32, Repr),
    LoadRel(u32, Repr),
    Load(Box<DynPlace>, Repr),
    /// Address of an aggregate (STRING, array, structure) or the target of a VAR_IN_OUT.
    AddrOf(Place),
    /// Byte address of a place: the value of a pointer, reference or interface.
    RefOf(Place),
    Un(Un, Box<Expr>),
    /// Both operands in one allocation, next to each other in memory.
    Bin(Bin, Box<(Expr, Expr)>),
    /// Specialised shapes of the commonest PLC expressions (contacts and comparisons):
    /// `NOT a`, `a op b` on two absolute addresses, `e op constant`.
    NotAbs(u32),
    BinAbs(Bin, u32, u32, Repr, Repr),
    BinK(Bin, Box<Expr>, u64),
    /// `a op b op c ...` for AND, OR or XOR of three operands or more, evaluated left to
    /// right in one node: the conditions of PLC logic are long chains of these.
    Chain(Bin, Vec<Expr>),
    Conv(Conv, Box<Expr>),
    /// A built-in; string results go to the static temporary at `dest`; the flag says
    /// its strings are WSTRINGs.
    Builtin(Builtin, Box<[Expr]>, u32, bool),
    Call(Box<FnCall>),
    CallMethod(Box<MethodCall>),
    /// A method called through an interface, a reference or THIS: the instance's type
    /// tag picks the implementation.
    CallVirtual(Box<VirtualCall>),
    /// A call with `EN` and/or `ENO` inside an expression.
    Enabled(Box<EnabledCall>),
}

/// `F(EN := c, ..., ENO => v)` in an expression: the call runs only while `en` is TRUE
/// (its value is then the call's, else 0), and ENO is stored whether it ran.
#[derive(Debug)]
pub(crate) struct EnabledCall {
    pub en: Expr,
    pub call: Expr,
    /// ENO's target: place, its representation, bit of a word, negated (`NOT ENO =>`).
    pub eno: Option<(Place, Repr, Option<u8>, bool)>,
}

/// A method call resolved at run time by the type tag in the instance's first 8 bytes.
#[derive(Debug)]
pub(crate) struct VirtualCall {
    pub instance: Place,
    /// (type tag, index into `calls`).
    pub cases: Box<[(u64, u32)]>,
    pub calls: Box<[FnCall]>,
}

/// How a value is stored into a location.
#[derive(Debug, Clone, Copy)]
#[repr(u8)]
pub(crate) enum Store {
    Scalar(Repr),
    Range(i64, i64, Repr),
    /// A STRING (or a WSTRING, flag set) of this capacity.
    String(u16, bool),
    /// Bytes copied from the address the value holds.
    Block(u32),
}

/// One input (or VAR_IN_OUT address) of a call: evaluated into `temp` unless the call is
/// direct, then copied to the parameter.
#[derive(Debug)]
pub(crate) struct ArgIn {
    pub value: Expr,
    pub temp: u32,
    pub param: u32,
    pub store: Store,
}

/// One `name => target` output assignment of a call.
#[derive(Debug)]
pub(crate) struct ArgOut {
    pub param: u32,
    /// How the parameter is stored (for scalars).
    pub src: Repr,
    pub target: Place,
    pub store: Store,
    pub negate: bool,
    /// Wrap the value to this width on the way (a counter's INT CV into a WORD).
    pub wrap: Option<IntKind>,
}

#[derive(Debug)]
pub(crate) struct FnCall {
    pub func: u32,
    /// No argument calls a user function, so parameters can be written directly.
    pub direct: bool,
    pub args: Box<[ArgIn]>,
    pub outs: Box<[ArgOut]>,
}

/// A METHOD call: a function-like call whose body addresses the instance.
#[derive(Debug)]
pub(crate) struct MethodCall {
    pub instance: Place,
    pub call: FnCall,
}

#[derive(Debug)]
pub(crate) enum FbKind {
    Std(StdFb),
    User(u32),
}

#[derive(Debug)]
pub(crate) struct FbCall {
    pub instance: Place,
    pub kind: FbKind,
    pub direct: bool,
    pub args: Box<[ArgIn]>,
    pub outs: Box<[ArgOut]>,
}

#[derive(Debug)]
pub(crate) struct Stmt {
    pub line: u32,
    pub kind: StmtKind,
}

pub(crate) type Block = Box<[Stmt]>;

#[derive(Debug)]
pub(crate) struct CaseArm {
    pub ranges: Box<[(i64, i64)]>,
    pub body: Block,
}

#[derive(Debug)]
pub(crate) struct ForLoop {
    pub var: Place,
    pub repr: Repr,
    pub kind: IntKind,
    pub from: Expr,
    pub to: Expr,
    pub by: Expr,
    pub body: Block,
}

#[derive(Debug)]
#[repr(u8)]
pub(crate) enum StmtKind {
    Store(Place, Expr, Store),
    StoreBit(Place, Repr, u8, Expr),
    Eval(Expr),
    If(Box<[(Expr, Block)]>, Block),
    Case {
        selector: Expr,
        signed: bool,
        arms: Box<[CaseArm]>,
        default: Block,
    },
    For(Box<ForLoop>),
    While(Expr, Block),
    Repeat(Block, Expr),
    Exit,
    Continue,
    Return,
    CallFb(Box<FbCall>),
}

/// A user function or function block body.
#[derive(Debug)]
pub(crate) struct Body {
    pub pou: u32,
    /// Bytes re-initialised on every call (function frame, VAR_TEMP): the first byte
    /// (relative to the instance for FBs) and the initial values.
    pub reinit: Option<(u32, Box<[u8]>)>,
    pub stmts: Block,
}

#[derive(Debug)]
pub(crate) struct Function {
    pub body: Body,
    /// Address of the result (scalar) or of the result area (aggregate).
    pub result: u32,
    /// How a scalar result is stored.
    pub repr: Repr,
    pub aggregate: bool,
}

/// The code shared by all runtime instances of one program.
#[derive(Debug)]
pub(crate) struct Code {
    pub functions: Vec<Function>,
    pub fbs: Vec<Body>,
}

/// Control flow out of a statement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Flow {
    Next,
    Exit,
    Continue,
    Return,
    Fault,
}

/// The mutable state a scan works on.
pub(crate) struct Vm {
    pub mem: Vec<u8>,
    /// Base of the running FB instance.
    pub frame: u32,
    pub now: i64,
    pub budget: u64,
    pub fault: Option<FaultKind>,
    /// POU and line where the fault was seen first.
    pub fault_at: Option<(u32, u32)>,
    pub pou: u32,
    /// Auxiliary axes the PLCopen motion blocks command.
    pub axes: Vec<crate::plcopen::Axis>,
}

#[inline(always)]
fn f(v: u64) -> f64 {
    f64::from_bits(v)
}
#[inline(always)]
fn r(v: f64, f32: bool) -> u64 {
    if f32 {
        ((v as f32) as f64).to_bits()
    } else {
        v.to_bits()
    }
}

impl Vm {
    #[inline(always)]
    pub fn ld(&self, a: usize, r: Repr) -> u64 {
        r.load(&self.mem, a)
    }
    #[inline(always)]
    pub fn st(&mut self, a: usize, r: Repr, v: u64) {
        r.store(&mut self.mem, a, v)
    }
    #[cold]
    pub fn raise(&mut self, kind: FaultKind) {
        if self.fault.is_none() {
            self.fault = Some(kind);
        }
        self.budget = 0;
    }
    #[cold]
    fn fail_at(&mut self, line: u32) -> Flow {
        if self.fault.is_none() {
            self.fault = Some(FaultKind::WatchdogExceeded { budget: 0 });
        }
        if self.fault_at.is_none() {
            self.fault_at = Some((self.pou, line));
        }
        self.budget = 0;
        Flow::Fault
    }

    #[inline]
    fn base(&self, b: Base) -> usize {
        match b {
            Base::Abs(a) => a as usize,
            Base::Rel(o) => self.frame as usize + o as usize,
        }
    }

    /// Address of a place; an index out of range raises a fault and yields element 0.
    #[inline]
    pub fn addr(&mut self, c: &Code, p: &Place) -> usize {
        match p {
            Place::Abs(a) => *a as usize,
            Place::Rel(o) => self.frame as usize + *o as usize,
            Place::Dyn(d) => self.dyn_addr(c, d),
        }
    }

    fn dyn_addr(&mut self, c: &Code, d: &DynPlace) -> usize {
        let mut a = match &d.inner {
            Some(inner) => self.dyn_addr(c, inner),
            None => self.base(d.base),
        };
        if d.indirect {
            let target = self.ld(a, Repr::U64);
            if target == 0 {
                self.raise(FaultKind::NullReference);
                return 0;
            }
            // Inside memory here; the whole access is checked once the offset and the
            // indices are added (below).
            if target < FIRST_ADDRESS as u64 || target > self.mem.len() as u64 {
                self.raise(FaultKind::PointerOutOfRange { address: target });
                return 0;
            }
            a = target as usize;
        }
        a += d.offset as usize;
        for s in d.steps.iter() {
            let i = self.eval(c, &s.index) as i64;
            let k = i.wrapping_sub(s.low);
            if k < 0 || k as u64 >= s.len {
                self.raise(FaultKind::IndexOutOfRange {
                    index: i,
                    low: s.low,
                    high: s.low + s.len as i64 - 1,
                });
                continue;
            }
            a += k as usize * s.stride as usize;
        }
        if d.indirect && a.saturating_add(d.span as usize) > self.mem.len() {
            // The bytes accessed through the address (at its offset, at an index inside
            // the bounds of an array it points to) run past the memory's end.
            self.raise(FaultKind::PointerOutOfRange { address: a as u64 });
            return 0;
        }
        a
    }

    /// The value of an expression. The leaves most operands are (constants, variables at
    /// absolute addresses, negated contacts) are taken here, inlined where an operand is
    /// evaluated, so they cost no call; other nodes go to `eval_node`.
    #[inline(always)]
    pub fn eval(&mut self, c: &Code, e: &Expr) -> u64 {
        match e {
            Expr::Const(v) => *v,
            Expr::LoadAbs(a, r) => self.ld(*a as usize, *r),
            Expr::NotAbs(a) => self.ld(*a as usize, Repr::Bool) ^ 1,
            _ => self.eval_node(c, e),
        }
    }

    /// Every node but the leaves [`eval`](Self::eval) takes. Calls and built-ins are
    /// functions of their own, so that this frame, entered once per operator, stays small.
    #[inline(never)]
    fn eval_node(&mut self, c: &Code, e: &Expr) -> u64 {
        match e {
            Expr::LoadRel(o, r) => self.ld(self.frame as usize + *o as usize, *r),
            Expr::Un(op, a) => {
                let v = self.eval(c, a);
                match *op {
                    Un::NegI(k) => k.wrap((v as i64).wrapping_neg() as u64),
                    Un::NegR(s) => r(-f(v), s),
                    Un::NotBool => v ^ 1,
                    Un::NotBits(k) => k.wrap(!v),
                    Un::Bit(n) => (v >> n) & 1,
                }
            }
            Expr::Bin(op, ab) => {
                let x = self.eval(c, &ab.0);
                let y = self.eval(c, &ab.1);
                self.bin(*op, x, y)
            }
            Expr::BinAbs(op, a, b, ra, rb) => {
                let x = self.ld(*a as usize, *ra);
                let y = self.ld(*b as usize, *rb);
                self.bin(*op, x, y)
            }
            Expr::BinK(op, a, k) => {
                let x = self.eval(c, a);
                self.bin(*op, x, *k)
            }
            Expr::Chain(op, operands) => {
                let Some((first, rest)) = operands.split_first() else {
                    return 0;
                };
                let mut acc = self.eval(c, first);
                for e in rest {
                    let v = self.eval(c, e);
                    acc = self.bin(*op, acc, v);
                }
                acc
            }
            Expr::Conv(cv, a) => {
                let v = self.eval(c, a);
                conv(*cv, v)
            }
            Expr::Load(d, r) => {
                let a = self.dyn_addr(c, d);
                self.ld(a, *r)
            }
            Expr::AddrOf(p) | Expr::RefOf(p) => self.addr(c, p) as u64,
            // `eval` takes the leaves before it comes here.
            Expr::Const(_) | Expr::LoadAbs(..) | Expr::NotAbs(_) => self.eval(c, e),
            Expr::Builtin(b, args, dest, wide) => self.builtin(c, *b, args, *dest, *wide),
            Expr::Call(call) => self.call_fn(c, call),
            Expr::Enabled(g) => self.enabled_call(c, g),
            Expr::CallMethod(m) => {
                let inst = self.addr(c, &m.instance);
                self.call_fn_in(c, &m.call, Some(inst))
            }
            Expr::CallVirtual(v) => self.call_virtual(c, v),
        }
    }

    /// `F(EN := ..., ENO => ...)` inside an expression ([`EnabledCall`]).
    #[inline(never)]
    fn enabled_call(&mut self, c: &Code, g: &EnabledCall) -> u64 {
        let run = self.eval(c, &g.en) & 1 != 0;
        let v = if run { self.eval(c, &g.call) } else { 0 };
        if let Some((place, repr, bit, negate)) = &g.eno {
            let eno = run != *negate;
            let a = self.addr(c, place);
            if self.budget != 0 {
                match bit {
                    Some(b) => {
                        let old = self.ld(a, *repr);
                        let m = 1u64 << b;
                        self.st(a, *repr, if eno { old | m } else { old & !m });
                    }
                    None => self.st(a, *repr, eno as u64),
                }
            }
        }
        v
    }

    /// A method call through an interface, a reference or THIS ([`VirtualCall`]).
    #[inline(never)]
    fn call_virtual(&mut self, c: &Code, v: &VirtualCall) -> u64 {
        let inst = self.addr(c, &v.instance);
        if self.budget == 0 {
            return 0;
        }
        let tag = self.ld(inst, Repr::U64);
        let call = v
            .cases
            .iter()
            .find(|(t, _)| *t == tag)
            .and_then(|(_, k)| v.calls.get(*k as usize));
        match call {
            Some(call) => self.call_fn_in(c, call, Some(inst)),
            None => {
                self.raise(FaultKind::NullReference);
                0
            }
        }
    }

    /// A binary operator on register values, inlined into the evaluator: most operators
    /// are an instruction or two, less than a call.
    #[inline(always)]
    fn bin(&mut self, op: Bin, x: u64, y: u64) -> u64 {
        use std::cmp::Ordering;
        match op {
            Bin::AddI(k) => k.wrap(x.wrapping_add(y)),
            Bin::SubI(k) => k.wrap(x.wrapping_sub(y)),
            Bin::MulI(k) => k.wrap(x.wrapping_mul(y)),
            Bin::DivI(k) => {
                if y == 0 {
                    self.raise(FaultKind::DivisionByZero);
                    0
                } else if k.signed() {
                    k.wrap((x as i64).wrapping_div(y as i64) as u64)
                } else {
                    x / y
                }
            }
            Bin::ModI(k) => {
                if y == 0 {
                    self.raise(FaultKind::DivisionByZero);
                    0
                } else if k.signed() {
                    k.wrap((x as i64).wrapping_rem(y as i64) as u64)
                } else {
                    x % y
                }
            }
            Bin::AddR(s) => r(f(x) + f(y), s),
            Bin::SubR(s) => r(f(x) - f(y), s),
            Bin::MulR(s) => r(f(x) * f(y), s),
            Bin::DivR(s) => {
                if f(y) == 0.0 {
                    self.raise(FaultKind::DivisionByZero);
                    0f64.to_bits()
                } else {
                    r(f(x) / f(y), s)
                }
            }
            Bin::PowR(s) => r(f(x).powf(f(y)), s),
            Bin::And => x & y,
            Bin::Or => x | y,
            Bin::Xor => x ^ y,
            Bin::Eq => (x == y) as u64,
            Bin::Ne => (x != y) as u64,
            Bin::Lt(s) => (if s { (x as i64) < (y as i64) } else { x < y }) as u64,
            Bin::Le(s) => (if s { (x as i64) <= (y as i64) } else { x <= y }) as u64,
            Bin::Gt(s) => (if s { (x as i64) > (y as i64) } else { x > y }) as u64,
            Bin::Ge(s) => (if s { (x as i64) >= (y as i64) } else { x >= y }) as u64,
            Bin::EqR => (f(x) == f(y)) as u64,
            Bin::NeR => (f(x) != f(y)) as u64,
            Bin::LtR => (f(x) < f(y)) as u64,
            Bin::LeR => (f(x) <= f(y)) as u64,
            Bin::GtR => (f(x) > f(y)) as u64,
            Bin::GeR => (f(x) >= f(y)) as u64,
            Bin::CmpS(ord, equal_ok, wide) => {
                let o = strings::compare(&self.mem, x as usize, y as usize, wide);
                (o == ord || (equal_ok && o == Ordering::Equal)) as u64
            }
            Bin::MulTimeI => (x as i64).wrapping_mul(y as i64) as u64,
            Bin::DivTimeI => {
                if y == 0 {
                    self.raise(FaultKind::DivisionByZero);
                    0
                } else {
                    (x as i64).wrapping_div(y as i64) as u64
                }
            }
            Bin::MulTimeR => ((x as i64) as f64 * f(y)).round() as i64 as u64,
            Bin::DivTimeR => {
                if f(y) == 0.0 {
                    self.raise(FaultKind::DivisionByZero);
                    0
                } else {
                    ((x as i64) as f64 / f(y)).round() as i64 as u64
                }
            }
        }
    }

    /// Evaluates a standard function's call: every argument first (IEC has no lazy
    /// evaluation), then the function.
    #[inline(never)]
    fn builtin(&mut self, c: &Code, b: Builtin, args: &[Expr], dest: u32, wide: bool) -> u64 {
        match b {
            Builtin::AbsI(k) => {
                let v = self.arg(c, args, 0);
                if k.signed() {
                    k.wrap((v as i64).wrapping_abs() as u64)
                } else {
                    v
                }
            }
            Builtin::AbsR(s) => r(f(self.arg(c, args, 0)).abs(), s),
            Builtin::Sqrt(s) => r(f(self.arg(c, args, 0)).sqrt(), s),
            Builtin::Ln(s) => r(f(self.arg(c, args, 0)).ln(), s),
            Builtin::Log(s) => r(f(self.arg(c, args, 0)).log10(), s),
            Builtin::Exp(s) => r(f(self.arg(c, args, 0)).exp(), s),
            Builtin::Sin(s) => r(f(self.arg(c, args, 0)).sin(), s),
            Builtin::Cos(s) => r(f(self.arg(c, args, 0)).cos(), s),
            Builtin::Tan(s) => r(f(self.arg(c, args, 0)).tan(), s),
            Builtin::Asin(s) => r(f(self.arg(c, args, 0)).asin(), s),
            Builtin::Acos(s) => r(f(self.arg(c, args, 0)).acos(), s),
            Builtin::Atan(s) => r(f(self.arg(c, args, 0)).atan(), s),
            Builtin::Atan2(s) => {
                let y = self.arg(c, args, 0);
                let x = self.arg(c, args, 1);
                r(f(y).atan2(f(x)), s)
            }
            Builtin::Shl(k) => {
                let v = self.arg(c, args, 0);
                let n = self.arg(c, args, 1);
                if n >= 64 { 0 } else { k.wrap(v << n) }
            }
            Builtin::Shr(k) => {
                let v = self.arg(c, args, 0);
                let n = self.arg(c, args, 1);
                if k.signed() {
                    // Signed values are held sign-extended: an i64 shift fills with the sign.
                    k.wrap(((v as i64) >> n.min(63)) as u64)
                } else if n >= 64 {
                    0
                } else {
                    k.wrap(v >> n)
                }
            }
            Builtin::Rol(k) | Builtin::Ror(k) => {
                let v = self.arg(c, args, 0);
                let n = self.arg(c, args, 1);
                rotate(k, v, n, matches!(b, Builtin::Ror(_)))
            }
            Builtin::Now => self.now as u64,
            Builtin::Sel => {
                let g = self.arg(c, args, 0);
                let in0 = self.arg(c, args, 1);
                let in1 = self.arg(c, args, 2);
                if g & 1 != 0 { in1 } else { in0 }
            }
            Builtin::Mux => self.mux(c, args),
            Builtin::MaxI(signed) | Builtin::MinI(signed) => {
                let max = matches!(b, Builtin::MaxI(_));
                let mut acc = self.arg(c, args, 0);
                for i in 1..args.len() {
                    let v = self.arg(c, args, i);
                    if int_beyond(v, acc, signed, max) {
                        acc = v;
                    }
                }
                acc
            }
            Builtin::MaxR | Builtin::MinR => {
                let max = matches!(b, Builtin::MaxR);
                let mut acc = f(self.arg(c, args, 0));
                for i in 1..args.len() {
                    let v = f(self.arg(c, args, i));
                    if max && v > acc || !max && v < acc {
                        acc = v;
                    }
                }
                acc.to_bits()
            }
            Builtin::LimitI(s) => {
                let lo = self.arg(c, args, 0);
                let v = self.arg(c, args, 1);
                let hi = self.arg(c, args, 2);
                if s {
                    (v as i64).max(lo as i64).min(hi as i64) as u64
                } else {
                    v.max(lo).min(hi)
                }
            }
            Builtin::LimitR => {
                let lo = f(self.arg(c, args, 0));
                let v = f(self.arg(c, args, 1));
                let hi = f(self.arg(c, args, 2));
                v.max(lo).min(hi).to_bits()
            }
            Builtin::ConcatDate | Builtin::ConcatTod | Builtin::ConcatDt | Builtin::DayOfWeek => {
                let mut vals = [0u64; 7];
                for (i, slot) in vals.iter_mut().enumerate().take(args.len()) {
                    *slot = self.arg(c, args, i);
                }
                crate::dates::concat(b, &vals)
            }
            Builtin::Concat => self.concat(c, args, dest, wide),
            Builtin::Len
            | Builtin::Left
            | Builtin::Right
            | Builtin::Mid
            | Builtin::Insert
            | Builtin::Delete
            | Builtin::Replace
            | Builtin::Find
            | Builtin::IntToStr(_)
            | Builtin::RealToStr(_)
            | Builtin::TimeToStr
            | Builtin::BoolToStr
            | Builtin::StrToInt(_)
            | Builtin::StrToReal(_)
            | Builtin::StrToBool
            | Builtin::StrToTime
            | Builtin::StrToStr(_)
            | Builtin::MomentToStr(_)
            | Builtin::StrToMoment(_) => {
                let mut vals = [0u64; 8];
                for (i, slot) in vals.iter_mut().enumerate().take(args.len()) {
                    *slot = self.arg(c, args, i);
                }
                strings::builtin(
                    &mut self.mem,
                    b,
                    &vals[..args.len().min(8)],
                    dest as usize,
                    wide,
                )
            }
        }
    }

    /// Argument `i` of a built-in (0 past the end), evaluated inline.
    #[inline(always)]
    fn arg(&mut self, c: &Code, args: &[Expr], i: usize) -> u64 {
        match args.get(i) {
            Some(e) => self.eval(c, e),
            None => 0,
        }
    }

    /// MUX: the input the selector (the first argument) picks; a selector out of range
    /// raises a fault and gives 0. Every input is evaluated.
    fn mux(&mut self, c: &Code, args: &[Expr]) -> u64 {
        let k = args.first().map_or(0, |e| self.eval(c, e)) as i64;
        let n = args.len() as i64 - 1;
        let mut picked = 0;
        for (i, e) in args.iter().skip(1).enumerate() {
            let v = self.eval(c, e);
            if i as i64 == k {
                picked = v;
            }
        }
        if k < 0 || k >= n {
            self.raise(FaultKind::IndexOutOfRange {
                index: k,
                low: 0,
                high: n - 1,
            });
        }
        picked
    }

    /// CONCAT (extensible): the first string copied into the destination, each further one
    /// appended to it.
    fn concat(&mut self, c: &Code, args: &[Expr], dest: u32, wide: bool) -> u64 {
        let first = args.first().map_or(0, |e| self.eval(c, e));
        strings::copy(
            &mut self.mem,
            dest as usize,
            first as usize,
            crate::types::MAX_STRING_LEN,
            wide,
        );
        for e in args.iter().skip(1) {
            let v = self.eval(c, e);
            strings::append(&mut self.mem, dest as usize, v as usize, wide);
        }
        dest as u64
    }

    /// Stores `v` (a scalar, or the address of an aggregate) at byte address `a`.
    #[inline]
    fn store_at(&mut self, a: usize, v: u64, s: Store) {
        match s {
            Store::Scalar(r) => self.st(a, r, v),
            Store::Range(lo, hi, r) => {
                let x = v as i64;
                if x < lo || x > hi {
                    self.raise(FaultKind::SubrangeViolation {
                        value: x,
                        low: lo,
                        high: hi,
                    });
                } else {
                    self.st(a, r, v);
                }
            }
            Store::String(cap, wide) => strings::copy(&mut self.mem, a, v as usize, cap, wide),
            Store::Block(n) => {
                let src = v as usize;
                let n = n as usize;
                if src.checked_add(n).is_some_and(|e| e <= self.mem.len())
                    && a.checked_add(n).is_some_and(|e| e <= self.mem.len())
                {
                    self.mem.copy_within(src..src + n, a);
                }
            }
        }
    }

    /// Evaluates call inputs into parameters at `base + param`.
    #[inline(always)]
    fn pass_args(&mut self, c: &Code, args: &[ArgIn], base: usize, direct: bool) {
        if direct {
            for a in args {
                let v = self.eval(c, &a.value);
                let at = base + a.param as usize;
                // Scalars (a block's BOOL and TIME inputs) stored inline, without a call.
                match a.store {
                    Store::Scalar(r) => self.st(at, r, v),
                    other => self.store_at(at, v, other),
                }
            }
        } else {
            for a in args {
                let v = self.eval(c, &a.value);
                self.store_at(a.temp as usize, v, a.store);
            }
            for a in args {
                let v = match a.store {
                    Store::Scalar(r) | Store::Range(_, _, r) => self.ld(a.temp as usize, r),
                    Store::String(..) | Store::Block(_) => a.temp as u64,
                };
                self.store_at(base + a.param as usize, v, a.store);
            }
        }
    }

    /// Copies a call's `=>` outputs; most calls have none, and that costs no call.
    #[inline(always)]
    fn take_outputs(&mut self, c: &Code, outs: &[ArgOut], base: usize) {
        if !outs.is_empty() {
            self.copy_outputs(c, outs, base);
        }
    }

    #[inline(never)]
    fn copy_outputs(&mut self, c: &Code, outs: &[ArgOut], base: usize) {
        for o in outs {
            let src = base + o.param as usize;
            let v = match o.store {
                Store::Scalar(_) | Store::Range(..) => {
                    let v = self.ld(src, o.src);
                    let v = if o.negate { v ^ 1 } else { v };
                    match o.wrap {
                        Some(k) => k.wrap(v),
                        None => v,
                    }
                }
                Store::String(..) | Store::Block(_) => src as u64,
            };
            let a = self.addr(c, &o.target);
            self.store_at(a, v, o.store);
        }
    }

    fn reinit(&mut self, range: &Option<(u32, Box<[u8]>)>, base: usize) {
        if let Some((start, values)) = range {
            let dst = base + *start as usize;
            if let Some(d) = self.mem.get_mut(dst..dst + values.len()) {
                d.copy_from_slice(values);
            }
        }
    }

    fn call_fn(&mut self, c: &Code, call: &FnCall) -> u64 {
        self.call_fn_in(c, call, None)
    }

    /// Calls a function, or a method on the instance at `instance`: arguments and outputs
    /// are evaluated in the caller's frame, the body runs in the instance's.
    #[inline(never)]
    fn call_fn_in(&mut self, c: &Code, call: &FnCall, instance: Option<usize>) -> u64 {
        let Some(func) = c.functions.get(call.func as usize) else {
            return 0;
        };
        self.reinit(&func.body.reinit, 0);
        self.pass_args(c, &call.args, 0, call.direct);
        if self.budget == 0 {
            return 0;
        }
        let (saved_pou, saved_frame) = (self.pou, self.frame);
        self.pou = func.body.pou;
        if let Some(inst) = instance {
            self.frame = inst as u32;
        }
        let _ = self.exec_block(c, &func.body.stmts);
        self.pou = saved_pou;
        self.frame = saved_frame;
        if self.budget == 0 {
            return 0;
        }
        self.take_outputs(c, &call.outs, 0);
        if func.aggregate {
            func.result as u64
        } else {
            self.ld(func.result as usize, func.repr)
        }
    }

    fn call_fb(&mut self, c: &Code, call: &FbCall) {
        let inst = self.addr(c, &call.instance);
        self.pass_args(c, &call.args, inst, call.direct);
        if self.budget == 0 {
            return;
        }
        match call.kind {
            FbKind::Std(fb) => {
                // The block computes on register values in its cells (8 bytes each). The
                // program writes a member at its own width, which leaves a signed or
                // REAL input in another encoding: those are widened first.
                if fb.has_narrow_inputs() {
                    for (i, m) in fb.members().iter().enumerate() {
                        let r = Repr::of(m.1);
                        if m.2 == crate::stdfb::Dir::In
                            && matches!(r, Repr::I8 | Repr::I16 | Repr::I32 | Repr::F32)
                        {
                            let v = self.ld(inst + 8 * i, r);
                            self.st(inst + 8 * i, Repr::U64, v);
                        }
                    }
                }
                let end = inst.saturating_add(8 * fb.size() as usize);
                if let Some(s) = self.mem.get_mut(inst..end) {
                    let mut cells = crate::stdfb::Cells(s);
                    if fb.is_motion() {
                        crate::plcopen::run(fb, &mut cells, &mut self.axes);
                    } else {
                        fb.run(&mut cells, self.now);
                    }
                }
            }
            FbKind::User(id) => {
                let Some(body) = c.fbs.get(id as usize) else {
                    return;
                };
                let (saved_frame, saved_pou) = (self.frame, self.pou);
                self.frame = inst as u32;
                self.pou = body.pou;
                self.reinit(&body.reinit, inst);
                let _ = self.exec_block(c, &body.stmts);
                self.frame = saved_frame;
                self.pou = saved_pou;
                if self.budget == 0 {
                    return;
                }
            }
        }
        self.take_outputs(c, &call.outs, inst);
    }

    /// Runs a program body (absolute addresses) under POU id `pou`.
    pub fn run_program(&mut self, c: &Code, pou: u32, stmts: &[Stmt]) -> Flow {
        self.pou = pou;
        self.frame = 0;
        self.exec_block(c, stmts)
    }

    pub fn exec_block(&mut self, c: &Code, stmts: &[Stmt]) -> Flow {
        for s in stmts {
            let flow = self.exec(c, s);
            if self.budget <= 1 {
                return self.fail_at(s.line);
            }
            self.budget -= 1;
            if flow != Flow::Next {
                return flow;
            }
        }
        Flow::Next
    }

    /// One loop iteration's worth of watchdog budget.
    #[inline]
    fn tick(&mut self, line: u32) -> bool {
        if self.budget <= 1 {
            self.fail_at(line);
            return false;
        }
        self.budget -= 1;
        true
    }

    fn exec(&mut self, c: &Code, s: &Stmt) -> Flow {
        match &s.kind {
            StmtKind::Store(p, e, st) => {
                let v = self.eval(c, e);
                let a = self.addr(c, p);
                if self.budget == 0 {
                    // A fault in the value or the index: the assignment does not happen.
                    return Flow::Fault;
                }
                match st {
                    Store::Scalar(r) => self.st(a, *r, v),
                    _ => self.store_at(a, v, *st),
                }
            }
            StmtKind::StoreBit(p, r, bit, e) => {
                let v = self.eval(c, e);
                let a = self.addr(c, p);
                if self.budget == 0 {
                    return Flow::Fault;
                }
                let old = self.ld(a, *r);
                let m = 1u64 << bit;
                self.st(a, *r, if v & 1 != 0 { old | m } else { old & !m });
            }
            StmtKind::Eval(e) => {
                self.eval(c, e);
            }
            StmtKind::CallFb(call) => self.call_fb(c, call),
            StmtKind::If(branches, default) => {
                for (cond, body) in branches.iter() {
                    let v = self.eval(c, cond);
                    if self.budget == 0 {
                        return Flow::Fault;
                    }
                    if v & 1 != 0 {
                        return self.exec_block(c, body);
                    }
                }
                return self.exec_block(c, default);
            }
            StmtKind::Case {
                selector,
                signed,
                arms,
                default,
            } => {
                let v = self.eval(c, selector);
                if self.budget == 0 {
                    return Flow::Fault;
                }
                for arm in arms.iter() {
                    let hit = arm.ranges.iter().any(|&(lo, hi)| {
                        if *signed {
                            (v as i64) >= lo && (v as i64) <= hi
                        } else {
                            v >= lo as u64 && v <= hi as u64
                        }
                    });
                    if hit {
                        return self.exec_block(c, &arm.body);
                    }
                }
                return self.exec_block(c, default);
            }
            StmtKind::For(l) => return self.exec_for(c, l, s.line),
            StmtKind::While(cond, body) => loop {
                if self.eval(c, cond) & 1 == 0 {
                    return Flow::Next;
                }
                if !self.tick(s.line) {
                    return Flow::Fault;
                }
                match self.exec_block(c, body) {
                    Flow::Next | Flow::Continue => {}
                    Flow::Exit => return Flow::Next,
                    other => return other,
                }
            },
            StmtKind::Repeat(body, cond) => loop {
                if !self.tick(s.line) {
                    return Flow::Fault;
                }
                match self.exec_block(c, body) {
                    Flow::Next | Flow::Continue => {}
                    Flow::Exit => return Flow::Next,
                    other => return other,
                }
                if self.eval(c, cond) & 1 != 0 {
                    return Flow::Next;
                }
            },
            StmtKind::Exit => return Flow::Exit,
            StmtKind::Continue => return Flow::Continue,
            StmtKind::Return => return Flow::Return,
        }
        Flow::Next
    }

    fn exec_for(&mut self, c: &Code, l: &ForLoop, line: u32) -> Flow {
        let signed = l.kind.signed();
        let as_i = |v: u64| if signed { v as i64 as i128 } else { v as i128 };
        let mut i = as_i(self.eval(c, &l.from));
        let end = as_i(self.eval(c, &l.to));
        let step = as_i(self.eval(c, &l.by));
        if self.budget == 0 {
            return Flow::Fault;
        }
        if step == 0 {
            self.raise(FaultKind::ZeroForStep);
            return Flow::Fault;
        }
        loop {
            // The control variable holds every value tested, including the one that ends
            // the loop; the test runs on the unwrapped counter, so a loop up to the type's
            // maximum still ends.
            let a = self.addr(c, &l.var);
            self.st(a, l.repr, l.kind.wrap(i as u64));
            if (step > 0 && i > end) || (step < 0 && i < end) {
                return Flow::Next;
            }
            if !self.tick(line) {
                return Flow::Fault;
            }
            match self.exec_block(c, &l.body) {
                Flow::Next | Flow::Continue => {}
                Flow::Exit => return Flow::Next,
                other => return other,
            }
            i += step;
        }
    }
}

/// ROL (or ROR, `right`) of `v` by `n` bits within the width of `k`.
fn rotate(k: IntKind, v: u64, n: u64, right: bool) -> u64 {
    let bits = k.bits() as u64;
    let n = n % bits;
    let n = if right { (bits - n) % bits } else { n };
    if n == 0 {
        v
    } else {
        k.wrap((v << n) | (v >> (bits - n)))
    }
}

/// True when integer `v` is beyond `acc`: above it for MAX (`max`), below it for MIN.
fn int_beyond(v: u64, acc: u64, signed: bool, max: bool) -> bool {
    let (greater, less) = if signed {
        ((v as i64) > (acc as i64), (v as i64) < (acc as i64))
    } else {
        (v > acc, v < acc)
    };
    if max { greater } else { less }
}

/// Applies a conversion to a register value.
pub(crate) fn conv(cv: Conv, v: u64) -> u64 {
    match cv {
        Conv::Int(k) => k.wrap(v),
        Conv::IntToReal { signed, f32 } => r(if signed { v as i64 as f64 } else { v as f64 }, f32),
        Conv::RealToInt(k) => k.wrap(real_to_int(f(v).round_ties_even(), k)),
        Conv::RealTrunc(k) => k.wrap(real_to_int(f(v).trunc(), k)),
        Conv::ToF32 => r(f(v), true),
        Conv::IntToBool => (v != 0) as u64,
        Conv::RealToBool => (f(v) != 0.0) as u64,
        Conv::NsToMs => ((v as i64) / 1_000_000) as u64,
        Conv::MsToNs => (v as i64).wrapping_mul(1_000_000) as u64,
        Conv::NsToS => ((v as i64) / 1_000_000_000) as u64,
        Conv::SToNs => (v as i64).wrapping_mul(1_000_000_000) as u64,
        Conv::DayFloor => {
            ((v as i64)
                .div_euclid(crate::dates::NS_PER_DAY)
                .wrapping_mul(crate::dates::NS_PER_DAY)) as u64
        }
        Conv::DayRem => (v as i64).rem_euclid(crate::dates::NS_PER_DAY) as u64,
        Conv::RealMsToNs => (f(v) * 1e6).round() as i64 as u64,
        Conv::NsToRealMs(s) => r(v as i64 as f64 / 1e6, s),
        Conv::ToBcd(k) => {
            let mut x = v;
            let mut out = 0u64;
            let mut shift = 0;
            while x > 0 && shift < 64 {
                out |= (x % 10) << shift;
                x /= 10;
                shift += 4;
            }
            k.wrap(out)
        }
        Conv::FromBcd => {
            let mut out = 0u64;
            let mut mul = 1u64;
            let mut x = v;
            while x > 0 {
                out = out.wrapping_add((x & 0xf).min(9).wrapping_mul(mul));
                mul = mul.wrapping_mul(10);
                x >>= 4;
            }
            out
        }
    }
}

/// A real to an integer type (already rounded or truncated). IEC 61131-3 leaves a value
/// outside the target's range implementation-defined; here it saturates: the nearest end of
/// the range, and NaN gives 0 (as Rust's `as` casts and IEC 60559's conversions to integer
/// with clamping). CODESYS and TwinCAT hand such a value to the processor's conversion,
/// whose result (e.g. -2147483648 for any out-of-range DINT on x86) is neither near nor
/// repeatable across targets.
fn real_to_int(x: f64, k: IntKind) -> u64 {
    let (low, high) = k.range();
    let v: i128 = if x.is_nan() {
        0
    } else if x <= low as f64 {
        low
    } else if x >= high as f64 {
        high
    } else {
        x as i128
    };
    v as u64
}
