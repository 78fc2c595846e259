//! Syntax tree of a Structured Text compilation unit. Names are upper case.

use crate::error::Pos;
use crate::lexer::DirectAddr;

#[derive(Debug, Clone)]
pub(crate) struct Name {
    pub text: String,
    pub pos: Pos,
}

#[derive(Debug, Default)]
pub(crate) struct Unit {
    pub types: Vec<TypeDecl>,
    pub pous: Vec<Pou>,
    pub globals: Vec<VarBlock>,
    pub configs: Vec<Config>,
    pub interfaces: Vec<Interface>,
}

/// An INTERFACE: method and property prototypes.
#[derive(Debug)]
pub(crate) struct Interface {
    pub name: Name,
    pub extends: Vec<Name>,
    pub methods: Vec<Method>,
    pub properties: Vec<Property>,
}

/// A PROPERTY of a function block (or its prototype in an interface). The getter is a
/// method returning the property's type in a variable of the property's name; the setter
/// a method with one VAR_INPUT of the property's name.
#[derive(Debug)]
pub(crate) struct Property {
    pub name: Name,
    pub ty: TypeSpec,
    pub get: Option<Method>,
    pub set: Option<Method>,
}

#[derive(Debug)]
pub(crate) struct TypeDecl {
    pub name: Name,
    pub spec: TypeSpec,
    pub init: Option<Init>,
}

#[derive(Debug, Clone)]
pub(crate) enum TypeSpec {
    Named(Name),
    String {
        len: Option<Expr>,
        /// WSTRING.
        wide: bool,
        pos: Pos,
    },
    Array {
        dims: Vec<(Expr, Expr)>,
        elem: Box<TypeSpec>,
        pos: Pos,
    },
    /// A STRUCT, or a UNION (`union`: every field at offset 0, sharing its bytes).
    Struct {
        fields: Vec<VarDecl>,
        union: bool,
        pos: Pos,
    },
    Enum {
        values: Vec<(Name, Option<Expr>)>,
        base: Option<Name>,
        pos: Pos,
    },
    Subrange {
        base: Name,
        low: Expr,
        high: Expr,
    },
    /// `POINTER TO T`.
    Pointer(Box<TypeSpec>),
    /// `REFERENCE TO T` (and IEC's `REF_TO T`).
    Reference(Box<TypeSpec>, Pos),
}

#[derive(Debug, Clone)]
pub(crate) enum Init {
    Expr(Expr),
    /// `[a, b, n(c)]`: (repeat count, value).
    Array(Vec<(Option<Expr>, Init)>, Pos),
    /// `(field := value, ...)`.
    Struct(Vec<(Name, Init)>, Pos),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum VarKind {
    Local,
    Input,
    Output,
    InOut,
    Global,
    External,
    Temp,
    /// VAR_INST of a METHOD: kept in the instance between calls.
    Inst,
}

#[derive(Debug, Clone)]
pub(crate) struct VarBlock {
    pub kind: VarKind,
    pub constant: bool,
    pub retain: bool,
    pub decls: Vec<VarDecl>,
}

#[derive(Debug, Clone)]
pub(crate) struct VarDecl {
    pub names: Vec<Name>,
    pub at: Option<(DirectAddr, Pos)>,
    pub ty: TypeSpec,
    pub init: Option<Init>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PouKind {
    Program,
    Function,
    FunctionBlock,
}

#[derive(Debug)]
pub(crate) struct Pou {
    pub kind: PouKind,
    pub name: Name,
    /// `EXTENDS Base` of a function block.
    pub extends: Option<Name>,
    /// `IMPLEMENTS I1, I2` of a function block.
    pub implements: Vec<Name>,
    pub properties: Vec<Property>,
    pub ret: Option<TypeSpec>,
    pub vars: Vec<VarBlock>,
    pub methods: Vec<Method>,
    pub body: Vec<Stmt>,
}

/// A METHOD of a function block.
#[derive(Debug)]
pub(crate) struct Method {
    pub name: Name,
    pub ret: Option<TypeSpec>,
    pub vars: Vec<VarBlock>,
    pub body: Vec<Stmt>,
    /// PRIVATE or PROTECTED: callable only from inside the function block.
    pub private: bool,
}

#[derive(Debug)]
pub(crate) struct Config {
    pub name: Name,
    pub globals: Vec<VarBlock>,
    pub resources: Vec<Resource>,
}

#[derive(Debug)]
pub(crate) struct Resource {
    pub tasks: Vec<TaskDecl>,
    pub programs: Vec<ProgramInst>,
}

#[derive(Debug)]
pub(crate) struct TaskDecl {
    pub name: Name,
    pub interval: Option<Expr>,
    pub priority: Option<Expr>,
    pub single: Option<Expr>,
}

#[derive(Debug)]
pub(crate) struct ProgramInst {
    pub name: Name,
    pub task: Option<Name>,
    pub ty: Name,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BinOp {
    Or,
    Xor,
    And,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    Add,
    Sub,
    Mul,
    Div,
    Mod,
    Pow,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum UnOp {
    Neg,
    Not,
    Plus,
}

#[derive(Debug, Clone)]
pub(crate) enum Literal {
    Int(u128),
    Real(f64),
    Time(i128),
    Str(Vec<u8>),
    /// A WSTRING literal in UTF-16 code units.
    WStr(Vec<u16>),
    Bool(bool),
    Moment(crate::dates::Moment, i64),
}

#[derive(Debug, Clone)]
pub(crate) enum Expr {
    Lit(Literal, Pos),
    /// `INT#5`, `Mode#Idle`, `REAL#1`, `BOOL#TRUE`.
    Typed(Name, Box<Expr>),
    /// `Mode#Idle`.
    EnumValue(Name, Name),
    Var(Access),
    Direct(DirectAddr, Pos),
    Unary(UnOp, Box<Expr>, Pos),
    Binary(BinOp, Box<Expr>, Box<Expr>, Pos),
    Call(Name, Vec<Arg>, Pos),
    /// `instance.method(args)`: the instance path and the method name.
    MethodCall(Box<(Access, Name)>, Vec<Arg>, Pos),
}

impl Expr {
    pub fn pos(&self) -> Pos {
        match self {
            Expr::Lit(_, p)
            | Expr::Direct(_, p)
            | Expr::Unary(_, _, p)
            | Expr::Binary(_, _, _, p)
            | Expr::Call(_, _, p)
            | Expr::MethodCall(_, _, p) => *p,
            Expr::Typed(n, _) | Expr::EnumValue(n, _) => n.pos,
            Expr::Var(a) => a.root.pos,
        }
    }
}

/// A variable access path: `a.b[i, j].c.3`.
#[derive(Debug, Clone)]
pub(crate) struct Access {
    pub root: Name,
    pub parts: Vec<Part>,
}

#[derive(Debug, Clone)]
pub(crate) enum Part {
    Field(Name),
    Index(Vec<Expr>, Pos),
    Bit(u8, Pos),
    /// `^`: dereference a pointer (`p^`), or `THIS^` / `SUPER^`.
    Deref(Pos),
}

#[derive(Debug, Clone)]
pub(crate) enum Arg {
    Positional(Expr),
    /// `name := expr`
    Input(Name, Expr),
    /// `name => target` (target None for `name =>`, which discards)
    Output(Name, Option<Access>, bool),
}

#[derive(Debug, Clone)]
pub(crate) struct CaseArm {
    pub labels: Vec<(Expr, Option<Expr>)>,
    pub body: Vec<Stmt>,
}

#[derive(Debug, Clone)]
pub(crate) enum Stmt {
    Assign(Access, Expr, Pos),
    /// `r REF= x`: point a REFERENCE at a variable.
    RefAssign(Access, Expr, Pos),
    /// A call of an FB instance or a function as a statement.
    Call(Access, Vec<Arg>, Pos),
    If(Vec<(Expr, Vec<Stmt>)>, Vec<Stmt>, Pos),
    Case(Expr, Vec<CaseArm>, Vec<Stmt>, Pos),
    For {
        var: Name,
        from: Expr,
        to: Expr,
        by: Option<Expr>,
        body: Vec<Stmt>,
        pos: Pos,
    },
    While(Expr, Vec<Stmt>, Pos),
    Repeat(Vec<Stmt>, Expr, Pos),
    Exit(Pos),
    Continue(Pos),
    Return(Pos),
    Empty,
}
