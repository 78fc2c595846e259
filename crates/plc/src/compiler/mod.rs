//! Type checker and code generator: from the syntax tree to [`Program`].
//!
//! `declare` lays out types, POUs and variables; `stmt`, `expr` and `call` compile bodies.
//!
//! Memory is laid out once: globals, program instances, function frames (functions cannot
//! recurse in IEC 61131-3, so each has one static frame), call temporaries and string
//! temporaries all get absolute slots; function block bodies address their instance
//! relative to the instance base, so one body serves every instance.

mod call;
mod declare;
mod expr;
mod stmt;

use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::time::Duration;

use crate::ast::{
    self, Access, Arg, BinOp, Expr as AExpr, Init, Literal, Name, Part, PouKind, TypeSpec, UnOp,
    VarKind,
};
use crate::error::{CompileError, CompileErrors, ErrorKind, Pos, Warning};
use crate::lexer::{AddrSize, Area, DirectAddr};
use crate::program::{FbLayout, Located, Program, ProgramInstance, Symbol, TaskDesc, area_index};
use crate::stdfb::{Dir, StdFb};
use crate::types::Repr;
use crate::types::*;
use crate::vm::{
    self, ArgIn, ArgOut, Base, Bin, Block, Builtin, CaseArm, Code, Conv, DynPlace, FbCall, FbKind,
    FnCall, ForLoop, IndexStep, Place, Stmt, StmtKind, Store, Un,
};

pub(crate) type R<T> = Result<T, CompileError>;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Loc {
    Abs(u32),
    Rel(u32),
    IndAbs(u32),
    IndRel(u32),
}

#[derive(Debug, Clone)]
struct VarInfo {
    ty: Type,
    loc: Loc,
    kind: VarKind,
    constant: bool,
    const_val: Option<u64>,
    input_area: bool,
}

/// Compile-time type of an expression: a real type or an untyped literal.
#[derive(Debug, Clone)]
pub(crate) enum Ty {
    T(Type),
    AnyInt(i128),
    AnyReal(f64),
}

pub(crate) struct TE {
    pub(crate) ty: Ty,
    pub(crate) e: vm::Expr,
}

#[derive(Debug, Clone)]
struct Member {
    name: String,
    ty: Type,
    offset: u32,
    kind: VarKind,
    constant: bool,
    retain: bool,
}

struct FbInfo {
    name: String,
    members: Vec<Member>,
    size: u32,
    template: Vec<u8>,
    std: Option<StdFb>,
    body: u32,
    /// METHODs, inherited ones included: name, function id, private.
    methods: Vec<(String, u32, bool)>,
    /// `EXTENDS`: the base function block.
    base: Option<u32>,
    /// `IMPLEMENTS`: the interfaces named.
    interfaces: Vec<u32>,
    /// PROPERTYs, inherited ones included.
    properties: Vec<PropInfo>,
    /// Slots of the members this block declares itself start here (after the base's).
    own_start: u32,
}

#[derive(Debug, Clone)]
struct PropInfo {
    name: String,
    get: Option<u32>,
    set: Option<u32>,
    private: bool,
}

/// An INTERFACE: the methods (with their result type) and properties it requires.
struct IfaceInfo {
    name: String,
    extends: Vec<u32>,
    methods: Vec<(String, Option<Type>)>,
    properties: Vec<(String, Type)>,
}

/// What a method-like call on an instance invokes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Invoke {
    Method,
    Get,
    Set,
}

/// The instance a method or property is called on: its place (None: the running
/// instance), its static type, and the types it may have at run time.
pub(crate) struct Receiver {
    instance: Option<Place>,
    static_fb: Option<u32>,
    iface: Option<u32>,
    cands: Vec<u32>,
}

/// The first slot of every user function block instance holds its type tag (the FB
/// type id + 1), for calls through interfaces, references and THIS.
const TAG_OFFSET: u32 = 0;

struct FuncInfo {
    name: String,
    pou: u32,
    ret: Option<Type>,
    result: u32,
    params: Vec<Member>,
    locals: HashMap<String, VarInfo>,
    frame: (u32, u32),
}

pub(crate) struct Scope {
    vars: HashMap<String, VarInfo>,
    kind: PouKind,
    pou: u32,
    loops: u32,
    /// Functions and methods called from this body (recursion check).
    calls: Vec<u32>,
    /// The function block whose body or method this is: its methods can be called bare.
    fb: Option<u32>,
    /// Control variables of the FOR loops being compiled: the body may not assign them.
    for_vars: Vec<String>,
}

enum Lookup<T> {
    Missing,
    Busy,
    Found(T),
}

pub(crate) struct Compiler<'a> {
    file: &'a str,
    /// Upper-case name -> its first spelling in the source, for messages.
    spelling: HashMap<String, String>,
    errors: Vec<CompileError>,
    image: Vec<u8>,
    type_asts: HashMap<String, &'a ast::TypeDecl>,
    named: HashMap<String, (Type, Option<Vec<u8>>)>,
    resolving: HashSet<String>,
    enums: Vec<EnumType>,
    enum_values: HashMap<String, Vec<(u32, i64)>>,
    structs: Vec<(StructType, Vec<u8>)>,
    fb_asts: HashMap<String, &'a ast::Pou>,
    fbs: Vec<FbInfo>,
    fb_by_name: HashMap<String, Lookup<u32>>,
    fn_asts: HashMap<String, &'a ast::Pou>,
    funcs: Vec<FuncInfo>,
    fn_by_name: HashMap<String, Lookup<u32>>,
    fn_calls: Vec<Vec<u32>>,
    /// Method function id -> its function block and declaration.
    method_asts: HashMap<u32, (u32, &'a ast::Method)>,
    method_names: HashSet<String>,
    globals: HashMap<String, VarInfo>,
    global_syms: Vec<Symbol>,
    located: Vec<Located>,
    pou_names: Vec<Arc<str>>,
    code_fns: Vec<Option<vm::Function>>,
    code_fbs: Vec<Option<vm::Body>>,
    string_lits: HashMap<Vec<u8>, u32>,
    warnings: Vec<Warning>,
    iface_asts: HashMap<String, &'a ast::Interface>,
    ifaces: Vec<IfaceInfo>,
    iface_by_name: HashMap<String, Lookup<u32>>,
    methods_declared: HashSet<u32>,
    /// CODESYS's implicit conversions ([`crate::Conversions::Codesys`]).
    codesys_conversions: bool,
}

fn err(file: &str, pos: Pos, kind: ErrorKind, msg: impl Into<String>) -> CompileError {
    CompileError::new(file, pos, kind, msg)
}

/// The names of the unit's POUs of one kind, in source order.
fn pous_of_kind(u: &ast::Unit, kind: PouKind) -> Vec<Name> {
    u.pous
        .iter()
        .filter(|p| p.kind == kind)
        .map(|p| p.name.clone())
        .collect()
}

fn elem_of(ty: &Ty) -> Option<Elem> {
    match ty {
        Ty::T(t) => t
            .scalar()
            .filter(|_| !matches!(t, Type::Enum(_)) && !t.is_address()),
        _ => None,
    }
}

fn real_flag(e: Elem) -> bool {
    e == Elem::Real
}

fn ik(e: Elem) -> IntKind {
    e.int_kind().unwrap_or(IntKind::I64)
}

/// Bytes a value of type `t` takes (CODESYS's SIZEOF).
fn size_of(c: &Compiler, t: &Type) -> u32 {
    match t {
        Type::String(n) => string_bytes(*n),
        Type::WString(n) => crate::types::wstring_bytes(*n),
        Type::Array(a) => (a.len() as u32).saturating_mul(a.elem_size),
        Type::Struct(id) => c.structs.get(*id as usize).map_or(1, |s| s.0.size),
        Type::Fb(id) => c.fbs.get(*id as usize).map_or(8, |f| f.size),
        t => t.scalar().map_or(8, Elem::size),
    }
}

/// Alignment of type `t`: its own size for an elementary value, its largest member's for
/// an aggregate (CODESYS's default `pack_mode`, natural alignment).
fn align_of(c: &Compiler, t: &Type) -> u32 {
    match t {
        Type::String(_) => 1,
        Type::WString(_) => 2,
        Type::Array(a) => align_of(c, &a.elem),
        Type::Struct(id) => c.structs.get(*id as usize).map_or(1, |s| s.0.align),
        Type::Fb(_) => 8,
        t => t.scalar().map_or(8, Elem::size),
    }
}

/// `off` rounded up to a multiple of `align` (a power of two).
fn align_up(off: u32, align: u32) -> u32 {
    off.saturating_add(align - 1) & !(align - 1)
}

/// The representation of a scalar type (8 raw bytes for anything else, which is never
/// loaded as a scalar).
fn repr_of(t: &Type) -> Repr {
    t.repr().unwrap_or(Repr::U64)
}

/// Limit on the bytes of one program, so a huge ARRAY declaration is a compile error, not
/// an allocation failure.
const MAX_BYTES: u64 = 128 << 20;

/// Where the lines of each source file start in the joined token stream.
#[derive(Debug, Clone, Default)]
pub(crate) struct LineMap {
    /// (first line in the joined stream, file name), in order.
    files: Vec<(u32, String)>,
}

impl LineMap {
    /// File name and line within it of a line of the joined stream.
    pub(crate) fn locate(&self, line: u32) -> (&str, u32) {
        let k = self.files.partition_point(|(start, _)| *start <= line);
        match self.files.get(k.saturating_sub(1)) {
            Some((start, f)) => (f.as_str(), line - start + 1),
            None => ("", line),
        }
    }
    fn fix(&self, e: &mut CompileError) {
        let (f, l) = self.locate(e.pos.line);
        e.file = f.to_string();
        e.pos.line = l;
    }
}

/// Compiles one program made of one or more source files (global variable lists, type
/// files, POU files), in the order given.
pub(crate) fn compile(
    sources: &[(&str, &str)],
    options: &crate::CompileOptions,
) -> Result<Program, CompileErrors> {
    let mut toks: Vec<crate::lexer::Token> = Vec::new();
    let mut spelling: HashMap<String, String> = HashMap::new();
    let mut lines = LineMap::default();
    let mut first_line = 1u32;
    for (text, file) in sources {
        let mut t = crate::lexer::tokenize_with(text, file, options.nested_comments)?;
        for (k, v) in spellings(text, &t) {
            spelling.entry(k).or_insert(v);
        }
        lines.files.push((first_line, file.to_string()));
        let shift = first_line - 1;
        for tok in &mut t {
            tok.pos.line += shift;
        }
        let n = text.bytes().filter(|b| *b == b'\n').count() as u32 + 1;
        first_line = first_line.saturating_add(n);
        if !toks.is_empty() {
            toks.pop(); // the previous file's end
        }
        toks.extend(t);
    }
    if toks.is_empty() {
        toks.push(crate::lexer::Token {
            kind: crate::lexer::Tok::Eof,
            pos: Pos { line: 1, col: 1 },
        });
    }
    let file = sources.first().map_or("", |s| s.1);
    let mut unit = crate::parser::parse(&toks, file).map_err(|mut e| {
        e.message = respell(&spelling, &e.message);
        lines.fix(&mut e);
        e
    })?;
    add_predefined_types(&mut unit, &mut spelling);
    let mut result = compile_unit(&unit, file, spelling, options);
    match &mut result {
        Ok(p) => {
            for w in &mut p.warnings {
                let (f, l) = lines.locate(w.pos.line);
                w.file = f.to_string();
                w.pos.line = l;
            }
            p.lines = lines;
        }
        Err(es) => es.0.iter_mut().for_each(|e| lines.fix(e)),
    }
    result
}

/// The PLCopen enumerations for MC_MoveAbsolute's and MC_MoveVelocity's Direction and the
/// blocks' BufferMode, numbered as TwinCAT numbers them (CODESYS's -1 for negative and 0
/// for the shortest way are taken as integers too).
const PREDEFINED_TYPES: &str = "TYPE
  MC_DIRECTION : (mcPositiveDirection := 1, mcShortestWay := 2, mcNegativeDirection := 3,
                  mcCurrentDirection := 4) INT;
  MC_BUFFER_MODE : (mcAborting := 0, mcBuffered := 1, mcBlendingLow := 2,
                    mcBlendingPrevious := 3, mcBlendingNext := 4, mcBlendingHigh := 5) INT;
END_TYPE";

/// Adds the predefined types the program does not declare itself (by any name).
fn add_predefined_types(unit: &mut ast::Unit, spelling: &mut HashMap<String, String>) {
    let Ok(toks) = crate::lexer::tokenize_with(PREDEFINED_TYPES, "", true) else {
        return;
    };
    let Ok(predefined) = crate::parser::parse(&toks, "") else {
        return;
    };
    for (k, v) in spellings(PREDEFINED_TYPES, &toks) {
        spelling.entry(k).or_insert(v);
    }
    let taken: HashSet<String> = unit
        .types
        .iter()
        .map(|t| &t.name.text)
        .chain(unit.pous.iter().map(|p| &p.name.text))
        .chain(unit.interfaces.iter().map(|i| &i.name.text))
        .cloned()
        .collect();
    for t in predefined.types {
        if !taken.contains(&t.name.text) {
            unit.types.push(t);
        }
    }
}

fn compile_unit(
    unit: &ast::Unit,
    file: &str,
    spelling: HashMap<String, String>,
    options: &crate::CompileOptions,
) -> Result<Program, CompileErrors> {
    let mut c = Compiler {
        spelling,
        file,
        errors: Vec::new(),
        image: Vec::new(),
        type_asts: HashMap::new(),
        named: HashMap::new(),
        resolving: HashSet::new(),
        enums: Vec::new(),
        enum_values: HashMap::new(),
        structs: Vec::new(),
        fb_asts: HashMap::new(),
        fbs: Vec::new(),
        fb_by_name: HashMap::new(),
        fn_asts: HashMap::new(),
        funcs: Vec::new(),
        fn_by_name: HashMap::new(),
        fn_calls: Vec::new(),
        method_asts: HashMap::new(),
        method_names: HashSet::new(),
        globals: HashMap::new(),
        global_syms: Vec::new(),
        located: Vec::new(),
        pou_names: Vec::new(),
        code_fns: Vec::new(),
        code_fbs: Vec::new(),
        string_lits: HashMap::new(),
        warnings: Vec::new(),
        iface_asts: HashMap::new(),
        ifaces: Vec::new(),
        iface_by_name: HashMap::new(),
        methods_declared: HashSet::new(),
        codesys_conversions: options.conversions == crate::Conversions::Codesys,
    };
    // Slot 0 is never a variable: a null pointer or reference points there.
    c.image.resize(vm::FIRST_ADDRESS, 0);
    let program = c.unit(unit);
    // A program instantiated twice reports its body's errors once.
    let mut seen = HashSet::new();
    c.errors
        .retain(|e| seen.insert((e.pos.line, e.pos.col, e.message.clone())));
    match program {
        Ok(mut p) if c.errors.is_empty() => {
            p.warnings = std::mem::take(&mut c.warnings);
            p.warnings.sort_by_key(|w| (w.pos.line, w.pos.col));
            Ok(p)
        }
        Ok(_) => Err(CompileErrors(c.errors)),
        Err(e) => {
            c.errors.push(e);
            c.errors.sort_by_key(|e| (e.pos.line, e.pos.col));
            Err(CompileErrors(c.errors))
        }
    }
}

impl<'a> Compiler<'a> {
    fn e(&self, pos: Pos, kind: ErrorKind, msg: impl Into<String>) -> CompileError {
        err(self.file, pos, kind, self.respell(&msg.into()))
    }

    /// Shows quoted names in messages as the source spells them.
    fn respell(&self, msg: &str) -> String {
        respell(&self.spelling, msg)
    }

    /// `n` bytes of static memory, 8-aligned (enough for any type).
    fn alloc(&mut self, n: u32, pos: Pos) -> R<u32> {
        let start = (self.image.len() as u64).next_multiple_of(8);
        if start + n as u64 > MAX_BYTES {
            return Err(self.e(
                pos,
                ErrorKind::Invalid,
                "program needs more than 128 MiB of memory",
            ));
        }
        self.image.resize((start + n as u64) as usize, 0);
        Ok(start as u32)
    }

    fn type_name(&self, t: &Type) -> String {
        match t {
            Type::Elem(e) => e.name().into(),
            Type::String(n) => format!("STRING[{n}]"),
            Type::WString(n) => format!("WSTRING[{n}]"),
            Type::Enum(id) => self.enums[*id as usize].name.clone(),
            Type::Subrange(e, l, h) => format!("{}({l}..{h})", e.name()),
            Type::Array(a) => format!("ARRAY OF {}", self.type_name(&a.elem)),
            Type::Struct(id) => self.structs[*id as usize].0.name.clone(),
            Type::Fb(id) => self.fbs[*id as usize].name.clone(),
            Type::Pointer(t) => format!("POINTER TO {}", self.type_name(t)),
            Type::Reference(t) => format!("REFERENCE TO {}", self.type_name(t)),
            Type::Interface(id) => self.ifaces[*id as usize].name.clone(),
        }
    }
    fn ty_name(&self, t: &Ty) -> String {
        match t {
            Ty::T(t) => self.type_name(t),
            Ty::AnyInt(_) => "integer literal".into(),
            Ty::AnyReal(_) => "real literal".into(),
        }
    }

    fn new_pou_name(&mut self, name: &str) -> u32 {
        let shown = self.spelling.get(name).map_or(name, String::as_str);
        self.pou_names.push(Arc::from(shown));
        (self.pou_names.len() - 1) as u32
    }

    // ---------------------------------------------------------------- unit

    /// Compiles a whole unit in the order its parts depend on each other: names, types,
    /// globals, POU interfaces, bodies, then the program instances and tasks that run them.
    fn unit(&mut self, u: &'a ast::Unit) -> R<Program> {
        let programs = self.register_names(u)?;
        self.declare_types(u);
        // Globals first: their constants may bound the arrays of blocks and functions.
        self.declare_globals(u);
        let (fb_names, fn_names) = self.declare_interfaces(u);
        // Bodies refer to the interfaces of every POU: stop before compiling any body if
        // an interface is wrong.
        if !self.errors.is_empty() {
            return Err(self.errors.remove(0));
        }
        self.compile_bodies(&fb_names, &fn_names)?;
        let (instances, tasks) = self.instances_and_tasks(u, &programs)?;
        if !self.errors.is_empty() {
            return Err(self.errors.remove(0));
        }
        self.finish_program(u, instances, tasks)
    }

    /// Files every type, interface, function, function block and program under its name,
    /// so that declarations can refer to each other in any order; returns the programs.
    fn register_names(&mut self, u: &'a ast::Unit) -> R<Vec<&'a ast::Pou>> {
        let mut seen: HashMap<String, Pos> = HashMap::new();
        for t in &u.types {
            self.check_new_name(&mut seen, &t.name)?;
            self.type_asts.insert(t.name.text.clone(), t);
        }
        for i in &u.interfaces {
            self.check_new_name(&mut seen, &i.name)?;
            self.iface_asts.insert(i.name.text.clone(), i);
        }
        let mut programs: Vec<&'a ast::Pou> = Vec::new();
        for p in &u.pous {
            self.check_new_name(&mut seen, &p.name)?;
            match p.kind {
                PouKind::Function => {
                    self.fn_asts.insert(p.name.text.clone(), p);
                }
                PouKind::FunctionBlock => {
                    self.fb_asts.insert(p.name.text.clone(), p);
                }
                PouKind::Program => programs.push(p),
            }
        }
        Ok(programs)
    }

    /// A top-level name may neither shadow a standard name nor be declared twice.
    fn check_new_name(&self, seen: &mut HashMap<String, Pos>, n: &Name) -> R<()> {
        if Elem::from_name(&n.text).is_some()
            || StdFb::from_name(&n.text).is_some()
            || n.text == "STRING"
        {
            return Err(self.e(
                n.pos,
                ErrorKind::Duplicate,
                format!("'{}' is a standard name", n.text),
            ));
        }
        if let Some(p) = seen.insert(n.text.clone(), n.pos) {
            return Err(self.e(
                n.pos,
                ErrorKind::Duplicate,
                format!("'{}' is already declared at line {}", n.text, p.line),
            ));
        }
        Ok(())
    }

    /// Lays out the named types; errors are collected so that one run reports them all.
    fn declare_types(&mut self, u: &ast::Unit) {
        for t in &u.types {
            if let Err(e) = self.named_type(&t.name) {
                self.errors.push(e);
            }
        }
    }

    /// Lays out the global variables of the unit and of its configuration.
    fn declare_globals(&mut self, u: &ast::Unit) {
        let mut global_blocks: Vec<&ast::VarBlock> = u.globals.iter().collect();
        for cfg in &u.configs {
            global_blocks.extend(cfg.globals.iter());
        }
        for b in global_blocks {
            let scope = Scope {
                vars: HashMap::new(),
                kind: PouKind::Program,
                pou: 0,
                loops: 0,
                calls: Vec::new(),
                fb: None,
                for_vars: Vec::new(),
            };
            for d in &b.decls {
                if let Err(e) = self.declare_global(b, d, &scope) {
                    self.errors.push(e);
                }
            }
        }
    }

    /// Declares what callers see of each function block (members, methods, implemented
    /// interfaces), interface and function; returns the names of the function blocks and
    /// of the functions.
    fn declare_interfaces(&mut self, u: &ast::Unit) -> (Vec<Name>, Vec<Name>) {
        let fb_names = pous_of_kind(u, PouKind::FunctionBlock);
        for n in &fb_names {
            if let Err(e) = self.fb_type(n) {
                self.errors.push(e);
            }
        }
        for i in &u.interfaces {
            if let Err(e) = self.iface(&i.name) {
                self.errors.push(e);
            }
        }
        // Methods and interface checks need every block and interface declared first.
        for n in &fb_names {
            if let Err(e) = self.declare_methods(n) {
                self.errors.push(e);
            }
        }
        for n in &fb_names {
            if let Err(e) = self.check_implements(n) {
                self.errors.push(e);
            }
        }
        let fn_names = pous_of_kind(u, PouKind::Function);
        for n in &fn_names {
            if let Err(e) = self.func(n) {
                self.errors.push(e);
            }
        }
        (fb_names, fn_names)
    }

    /// Compiles the bodies of function blocks, methods and functions, then rejects
    /// recursion (IEC 61131-3 functions have one static frame each).
    fn compile_bodies(&mut self, fb_names: &[Name], fn_names: &[Name]) -> R<()> {
        for n in fb_names {
            if let Err(e) = self.fb_body(n) {
                self.errors.push(e);
            }
        }
        // In declaration order: a map's order changes from run to run, and with it the
        // numbering of temporaries and the order of the errors reported.
        let mut methods: Vec<u32> = self.method_asts.keys().copied().collect();
        methods.sort_unstable();
        for id in methods {
            if let Err(e) = self.method_body(id) {
                self.errors.push(e);
            }
        }
        for n in fn_names {
            if let Err(e) = self.fn_body(n) {
                self.errors.push(e);
            }
        }
        self.check_recursion(fn_names)
    }

    /// The program instances and the tasks that run them, sorted by priority. Without a
    /// CONFIGURATION every program gets one instance run by the DEFAULT task.
    fn instances_and_tasks(
        &mut self,
        u: &'a ast::Unit,
        programs: &[&'a ast::Pou],
    ) -> R<(Vec<ProgramInstance>, Vec<TaskDesc>)> {
        let mut instances = Vec::new();
        let mut tasks: Vec<TaskDesc> = Vec::new();
        let mut default_task: Vec<usize> = Vec::new();
        if u.configs.len() > 1 {
            return Err(self.e(
                u.configs[1].name.pos,
                ErrorKind::Invalid,
                "only one CONFIGURATION per program is supported",
            ));
        }
        if let Some(cfg) = u.configs.first() {
            self.configure(cfg, programs, &mut instances, &mut tasks, &mut default_task)?;
        } else {
            for p in programs {
                let idx = instances.len();
                instances.push(self.program_instance(p, &p.name.text)?);
                default_task.push(idx);
            }
        }
        // A PROGRAM the configuration does not instantiate is still checked: it gets an
        // instance of its own name that no task runs.
        for p in programs {
            let used = instances.iter().any(|i| i.pou_type == p.name.text);
            if !used && !instances.iter().any(|i| i.name == p.name.text) {
                instances.push(self.program_instance(p, &p.name.text)?);
            }
        }
        if !default_task.is_empty() {
            tasks.push(TaskDesc {
                name: "DEFAULT".into(),
                interval: None,
                priority: u32::MAX,
                trigger: None,
                trigger_slot: None,
                programs: default_task
                    .iter()
                    .map(|i| instances[*i].name.clone())
                    .collect(),
                program_ids: default_task,
            });
        }
        tasks.sort_by_key(|t| t.priority);
        Ok((instances, tasks))
    }

    /// Declares the tasks and program instances of each resource of a CONFIGURATION; an
    /// instance with no task goes to `default_task`.
    fn configure(
        &mut self,
        cfg: &ast::Config,
        programs: &[&'a ast::Pou],
        instances: &mut Vec<ProgramInstance>,
        tasks: &mut Vec<TaskDesc>,
        default_task: &mut Vec<usize>,
    ) -> R<()> {
        let prog_by_name: HashMap<&str, &'a ast::Pou> = programs
            .iter()
            .map(|p| (p.name.text.as_str(), *p))
            .collect();
        let mut inst_names: HashSet<String> = HashSet::new();
        for res in &cfg.resources {
            let first_task = tasks.len();
            for t in &res.tasks {
                if tasks.iter().any(|x| x.name == t.name.text) {
                    return Err(self.e(
                        t.name.pos,
                        ErrorKind::Duplicate,
                        format!("task '{}' declared twice", t.name.text),
                    ));
                }
                let task = self.task(t)?;
                tasks.push(task);
            }
            for pi in &res.programs {
                if !inst_names.insert(pi.name.text.clone()) {
                    return Err(self.e(
                        pi.name.pos,
                        ErrorKind::Duplicate,
                        format!("program instance '{}' declared twice", pi.name.text),
                    ));
                }
                let Some(pou) = prog_by_name.get(pi.ty.text.as_str()) else {
                    return Err(self.e(
                        pi.ty.pos,
                        ErrorKind::Undeclared,
                        format!("no PROGRAM named '{}'", pi.ty.text),
                    ));
                };
                let idx = instances.len();
                instances.push(self.program_instance(pou, &pi.name.text)?);
                match &pi.task {
                    // A program instance names a task of its own resource only.
                    Some(tn) => {
                        let Some(t) = tasks[first_task..].iter_mut().find(|t| t.name == tn.text)
                        else {
                            return Err(self.e(
                                tn.pos,
                                ErrorKind::Undeclared,
                                format!("no TASK named '{}' in this resource", tn.text),
                            ));
                        };
                        t.programs.push(pi.name.text.clone());
                        t.program_ids.push(idx);
                    }
                    None => default_task.push(idx),
                }
            }
        }
        Ok(())
    }

    /// A TASK declaration, with no programs yet: cyclic (INTERVAL), event (SINGLE) or
    /// neither.
    fn task(&mut self, t: &ast::TaskDecl) -> R<TaskDesc> {
        let interval = match &t.interval {
            Some(e) => {
                let ns = self.const_time(e)?;
                if ns <= 0 {
                    return Err(self.e(e.pos(), ErrorKind::Invalid, "INTERVAL must be positive"));
                }
                Some(Duration::from_nanos(ns as u64))
            }
            None => None,
        };
        let (trigger, trigger_slot) = match &t.single {
            Some(s) => {
                if interval.is_some() {
                    return Err(self.e(
                        s.pos(),
                        ErrorKind::Invalid,
                        "a task has either INTERVAL (cyclic) or SINGLE (event), not both",
                    ));
                }
                let (name, slot) = self.trigger_variable(s)?;
                (Some(name), Some(slot))
            }
            None => (None, None),
        };
        let priority = match &t.priority {
            Some(e) => {
                let v = self.const_int(e)?;
                u32::try_from(v).map_err(|_| {
                    self.e(e.pos(), ErrorKind::Invalid, "PRIORITY must be 0 or more")
                })?
            }
            None => 0,
        };
        Ok(TaskDesc {
            name: t.name.text.clone(),
            interval,
            priority,
            trigger,
            trigger_slot,
            programs: Vec::new(),
            program_ids: Vec::new(),
        })
    }

    /// Moves what was compiled into the [`Program`].
    fn finish_program(
        &mut self,
        u: &ast::Unit,
        instances: Vec<ProgramInstance>,
        tasks: Vec<TaskDesc>,
    ) -> R<Program> {
        let image_sizes = self.located_image_sizes();
        // Every body compiled when no error was reported; a missing one is reported, never
        // run.
        let missing = || {
            err(
                self.file,
                Pos::default(),
                ErrorKind::Invalid,
                "a POU body failed to compile",
            )
        };
        let functions = self
            .code_fns
            .drain(..)
            .collect::<Option<Vec<_>>>()
            .ok_or_else(missing)?;
        let fbs = self
            .code_fbs
            .drain(..)
            .collect::<Option<Vec<_>>>()
            .ok_or_else(missing)?;
        Ok(Program {
            file: self.file.to_string(),
            code: Code { functions, fbs },
            init: std::mem::take(&mut self.image),
            globals: std::mem::take(&mut self.global_syms),
            instances,
            tasks,
            pou_names: std::mem::take(&mut self.pou_names),
            enums: std::mem::take(&mut self.enums),
            structs: self.structs.drain(..).map(|s| s.0).collect(),
            fbs: self.fb_layouts(),
            located: std::mem::take(&mut self.located),
            warnings: Vec::new(),
            lines: LineMap::default(),
            image_sizes,
            pou_count: u.pous.len(),
        })
    }

    /// The size in bytes of the input, output and memory images: up to the end of the
    /// highest located variable of each.
    fn located_image_sizes(&self) -> [usize; 3] {
        let mut sizes = [0usize; 3];
        for l in &self.located {
            let a = area_index(l.at.area);
            sizes[a] = sizes[a].max(l.at.byte_offset() + l.at.byte_len());
        }
        sizes
    }

    /// The member layout of each function block, as the runtime and its users see it.
    fn fb_layouts(&self) -> Vec<FbLayout> {
        self.fbs
            .iter()
            .map(|f| FbLayout {
                name: f.name.clone(),
                members: f
                    .members
                    .iter()
                    .map(|m| Symbol {
                        name: m.name.clone(),
                        ty: m.ty.clone(),
                        addr: m.offset,
                        kind: m.kind,
                        retain: m.retain,
                        indirect: m.kind == VarKind::InOut,
                    })
                    .collect(),
            })
            .collect()
    }

    /// The BOOL global (or `%IX`/`%QX`/`%MX` address) named by a task's SINGLE.
    fn trigger_variable(&mut self, e: &AExpr) -> R<(String, u32)> {
        let name = match e {
            AExpr::Var(a) if a.parts.is_empty() => a.root.text.clone(),
            AExpr::Direct(d, pos) => {
                self.direct_var(d, *pos)?;
                d.to_string()
            }
            _ => {
                return Err(self.e(
                    e.pos(),
                    ErrorKind::Invalid,
                    "SINGLE needs a BOOL global variable",
                ));
            }
        };
        match self.globals.get(&name) {
            Some(VarInfo {
                ty,
                loc: Loc::Abs(slot),
                ..
            }) if ty.is_bool() => Ok((name, *slot)),
            Some(_) => Err(self.e(
                e.pos(),
                ErrorKind::TypeMismatch,
                "SINGLE needs a BOOL global variable",
            )),
            None => Err(self.e(
                e.pos(),
                ErrorKind::Undeclared,
                format!("no global '{name}'"),
            )),
        }
    }

    fn check_recursion(&self, names: &[Name]) -> R<()> {
        // Depth-first search for a cycle in the static call graph.
        fn visit(g: &[Vec<u32>], n: u32, state: &mut [u8]) -> bool {
            match state[n as usize] {
                1 => return true,
                2 => return false,
                _ => {}
            }
            state[n as usize] = 1;
            for &m in &g[n as usize] {
                if visit(g, m, state) {
                    return true;
                }
            }
            state[n as usize] = 2;
            false
        }
        let mut state = vec![0u8; self.fn_calls.len()];
        for i in 0..self.fn_calls.len() {
            if visit(&self.fn_calls, i as u32, &mut state) {
                let name = &self.funcs[i].name;
                let pos = match self.method_asts.get(&(i as u32)) {
                    Some((_, m)) => m.name.pos,
                    None => names
                        .iter()
                        .find(|n| &n.text == name)
                        .map_or(Pos::default(), |n| n.pos),
                };
                return Err(self.e(
                    pos,
                    ErrorKind::Invalid,
                    format!("function '{name}' calls itself (recursion is not allowed)"),
                ));
            }
        }
        Ok(())
    }

    // ---------------------------------------------------------------- constants

    fn const_value(&mut self, e: &AExpr, scope: &Scope) -> R<TE> {
        let mut sc = Scope {
            vars: scope.vars.clone(),
            kind: scope.kind,
            pou: scope.pou,
            loops: 0,
            calls: Vec::new(),
            fb: None,
            for_vars: Vec::new(),
        };
        let te = self.expr(e, &mut sc, None)?;
        match (&te.ty, &te.e) {
            (Ty::AnyInt(_) | Ty::AnyReal(_), _) | (_, vm::Expr::Const(_)) => Ok(te),
            _ => Err(self.e(
                e.pos(),
                ErrorKind::Invalid,
                "a constant expression is needed here",
            )),
        }
    }

    fn const_int_in(&mut self, e: &AExpr, scope: &Scope) -> R<i128> {
        let te = self.const_value(e, scope)?;
        match te.ty {
            Ty::AnyInt(v) => Ok(v),
            Ty::T(t) => match (t.scalar(), &te.e) {
                (Some(el), vm::Expr::Const(v)) if el.int_kind().is_some() && el != Elem::Time => {
                    Ok(if ik(el).signed() || matches!(t, Type::Enum(_)) {
                        *v as i64 as i128
                    } else {
                        *v as i128
                    })
                }
                _ => Err(self.e(
                    e.pos(),
                    ErrorKind::TypeMismatch,
                    "an integer constant is needed here",
                )),
            },
            Ty::AnyReal(_) => Err(self.e(
                e.pos(),
                ErrorKind::TypeMismatch,
                "an integer constant is needed here",
            )),
        }
    }

    fn const_int(&mut self, e: &AExpr) -> R<i128> {
        let scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::Program,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
            fb: None,
            for_vars: Vec::new(),
        };
        self.const_int_in(e, &scope)
    }

    fn const_time(&mut self, e: &AExpr) -> R<i64> {
        let scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::Program,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
            fb: None,
            for_vars: Vec::new(),
        };
        let te = self.const_value(e, &scope)?;
        match (&te.ty, &te.e) {
            (Ty::T(Type::Elem(Elem::Time)), vm::Expr::Const(v)) => Ok(*v as i64),
            _ => Err(self.e(
                e.pos(),
                ErrorKind::TypeMismatch,
                "a TIME constant is needed here",
            )),
        }
    }
}

/// Replaces every quoted upper-case name in `msg` by its spelling in the source.
fn respell(spelling: &HashMap<String, String>, msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    for (i, part) in msg.split('\'').enumerate() {
        if i > 0 {
            out.push('\'');
        }
        let quoted = i % 2 == 1;
        out.push_str(if quoted {
            spelling.get(part).map_or(part, String::as_str)
        } else {
            part
        });
    }
    out
}

/// First spelling of every identifier (identifiers are ASCII, so the upper-case text has
/// the length of the original).
fn spellings(src: &str, toks: &[crate::lexer::Token]) -> HashMap<String, String> {
    let mut line_starts = vec![0usize];
    line_starts.extend(src.match_indices('\n').map(|(i, _)| i + 1));
    let mut map = HashMap::new();
    for t in toks {
        if let crate::lexer::Tok::Ident(up) = &t.kind {
            if map.contains_key(up) {
                continue;
            }
            let start = line_starts
                .get(t.pos.line as usize - 1)
                .map(|s| s + t.pos.col as usize - 1);
            if let Some(raw) = start.and_then(|s| src.get(s..s + up.len())) {
                map.insert(up.clone(), raw.to_string());
            }
        }
    }
    map
}

fn t_root(t: &Option<Access>) -> Pos {
    t.as_ref().map_or(Pos::default(), |a| a.root.pos)
}

fn contains_user_call(e: &AExpr, c: &Compiler) -> bool {
    match e {
        // Methods use static frames like functions.
        AExpr::MethodCall(..) => true,
        AExpr::Call(n, args, _) => {
            c.fn_asts.contains_key(&n.text)
                || c.method_names.contains(&n.text)
                || args.iter().any(|a| match a {
                    Arg::Positional(e) | Arg::Input(_, e) => contains_user_call(e, c),
                    Arg::Output(..) => false,
                })
        }
        AExpr::Unary(_, a, _) | AExpr::Typed(_, a) => contains_user_call(a, c),
        AExpr::Binary(_, a, b, _) => contains_user_call(a, c) || contains_user_call(b, c),
        AExpr::Var(a) => a.parts.iter().any(
            |p| matches!(p, Part::Index(ix, _) if ix.iter().any(|e| contains_user_call(e, c))),
        ),
        _ => false,
    }
}

/// A structure field's offset, type, type template and initializer.
type FieldInit<'i> = (u32, Type, Option<Vec<u8>>, Option<&'i Init>);

/// An lvalue under construction.
struct Lv {
    ty: Type,
    base: Base,
    indirect: bool,
    offset: u32,
    steps: Vec<IndexStep>,
    bit: Option<u8>,
    readonly: Option<(ErrorKind, String)>,
    const_val: Option<u64>,
    /// The base is a pointer at a computed place.
    inner: Option<Box<DynPlace>>,
    /// Writing it deserves a warning (a VAR_INPUT of the POU itself).
    warn_on_write: Option<String>,
}

impl Compiler<'_> {
    /// Declares the implicit global behind a directly represented variable (`%IX0.0`).
    fn direct_var(&mut self, d: &DirectAddr, pos: Pos) -> R<()> {
        let name = d.to_string();
        if self.globals.contains_key(&name) {
            return Ok(());
        }
        let e = match d.size {
            AddrSize::Bit => Elem::Bool,
            AddrSize::Byte => Elem::Byte,
            AddrSize::Word => Elem::Word,
            AddrSize::Double => Elem::DWord,
            AddrSize::Long => Elem::LWord,
        };
        let a = self.alloc(e.size(), pos)?;
        self.located.push(Located {
            at: *d,
            slot: a,
            elem: e,
        });
        let info = VarInfo {
            ty: Type::Elem(e),
            loc: Loc::Abs(a),
            kind: VarKind::Global,
            constant: false,
            const_val: None,
            input_area: d.area == Area::Input,
        };
        self.globals.insert(name.clone(), info);
        self.global_syms.push(Symbol {
            name,
            ty: Type::Elem(e),
            addr: a,
            kind: VarKind::Global,
            retain: false,
            indirect: false,
        });
        Ok(())
    }

    /// CODESYS's implicit conversions are on ([`crate::Conversions::Codesys`]).
    pub(crate) fn codesys_conversions(&self) -> bool {
        self.codesys_conversions
    }
    pub(crate) fn err_at(&self, pos: Pos, kind: ErrorKind, msg: impl Into<String>) -> CompileError {
        self.e(pos, kind, msg)
    }
    pub(crate) fn coerce_to(&self, te: TE, to: &Type, pos: Pos) -> R<vm::Expr> {
        self.coerce(te, to, pos)
    }
    pub(crate) fn conversion(&self, e: vm::Expr, f: Elem, t: Elem) -> vm::Expr {
        self.fold(self.convert(e, f, t))
    }
    pub(crate) fn folded(&self, e: vm::Expr) -> vm::Expr {
        self.fold(e)
    }
    pub(crate) fn new_string_temp(&mut self, pos: Pos, wide: bool) -> R<u32> {
        self.string_temp(pos, wide)
    }
    pub(crate) fn type_label(&self, t: &Ty) -> String {
        self.ty_name(t)
    }
    pub(crate) fn common_type(&self, a: &Ty, b: &Ty, pos: Pos) -> R<Type> {
        self.common(a, b, pos)
    }
    pub(crate) fn binary_op(&mut self, op: BinOp, l: TE, r: TE, pos: Pos) -> R<TE> {
        self.binary(op, l, r, pos)
    }
    pub(crate) fn te(ty: Ty, e: vm::Expr) -> TE {
        TE { ty, e }
    }
    pub(crate) fn te_parts(t: TE) -> (Ty, vm::Expr) {
        (t.ty, t.e)
    }
}

pub(crate) fn builtin_expr(b: Builtin, args: Vec<vm::Expr>, dest: u32) -> vm::Expr {
    builtin_expr_wide(b, args, dest, false)
}

/// A built-in on WSTRINGs (`wide`) or STRINGs.
pub(crate) fn builtin_expr_wide(
    b: Builtin,
    args: Vec<vm::Expr>,
    dest: u32,
    wide: bool,
) -> vm::Expr {
    vm::Expr::Builtin(b, args.into_boxed_slice(), dest, wide)
}

pub(crate) fn literal_elem(t: &Ty) -> Option<Elem> {
    elem_of(t)
}
