//! Type checker and code generator: from the syntax tree to [`Program`].
//!
//! Memory is laid out once: globals, program instances, function frames (functions cannot
//! recurse in IEC 61131-3, so each has one static frame), call temporaries and string
//! temporaries all get absolute slots; function block bodies address their instance
//! relative to the instance base, so one body serves every instance.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::time::Duration;

use crate::ast::{
    self, Access, Arg, BinOp, Expr as AExpr, Init, Literal, Name, Part, PouKind, TypeSpec, UnOp,
    VarKind,
};
use crate::error::{CompileError, CompileErrors, ErrorKind, Pos};
use crate::lexer::{AddrSize, Area, DirectAddr};
use crate::program::{FbLayout, Located, Program, ProgramInstance, Symbol, TaskDesc, area_index};
use crate::stdfb::{Dir, StdFb};
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
    template: Vec<u64>,
    std: Option<StdFb>,
    body: u32,
}

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
    /// Functions called from this body (recursion check).
    calls: Vec<u32>,
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
    image: Vec<u64>,
    type_asts: HashMap<String, &'a ast::TypeDecl>,
    named: HashMap<String, (Type, Option<Vec<u64>>)>,
    resolving: HashSet<String>,
    enums: Vec<EnumType>,
    enum_values: HashMap<String, Vec<(u32, i64)>>,
    structs: Vec<(StructType, Vec<u64>)>,
    fb_asts: HashMap<String, &'a ast::Pou>,
    fbs: Vec<FbInfo>,
    fb_by_name: HashMap<String, Lookup<u32>>,
    fn_asts: HashMap<String, &'a ast::Pou>,
    funcs: Vec<FuncInfo>,
    fn_by_name: HashMap<String, Lookup<u32>>,
    fn_calls: Vec<Vec<u32>>,
    globals: HashMap<String, VarInfo>,
    global_syms: Vec<Symbol>,
    located: Vec<Located>,
    pou_names: Vec<Arc<str>>,
    code_fns: Vec<Option<vm::Function>>,
    code_fbs: Vec<Option<vm::Body>>,
    string_lits: HashMap<Vec<u8>, u32>,
}

fn err(file: &str, pos: Pos, kind: ErrorKind, msg: impl Into<String>) -> CompileError {
    CompileError::new(file, pos, kind, msg)
}

fn elem_of(ty: &Ty) -> Option<Elem> {
    match ty {
        Ty::T(t) => t.scalar().filter(|_| !matches!(t, Type::Enum(_))),
        _ => None,
    }
}

fn real_flag(e: Elem) -> bool {
    e == Elem::Real
}

fn ik(e: Elem) -> IntKind {
    e.int_kind().unwrap_or(IntKind::I64)
}

fn size_of(c: &Compiler, t: &Type) -> u32 {
    match t {
        Type::Elem(_) | Type::Enum(_) | Type::Subrange(..) => 1,
        Type::String(n) => string_slots(*n),
        Type::Array(a) => (a.len() as u32).saturating_mul(a.elem_size),
        Type::Struct(id) => c.structs.get(*id as usize).map_or(1, |s| s.0.size),
        Type::Fb(id) => c.fbs.get(*id as usize).map_or(1, |f| f.size),
    }
}

/// Limit on the slots of one program, so a huge ARRAY declaration is a compile error, not
/// an allocation failure.
const MAX_SLOTS: u64 = 16 << 20;

pub(crate) fn compile(src: &str, file: &str) -> Result<Program, CompileErrors> {
    let toks = crate::lexer::tokenize(src, file)?;
    let unit = crate::parser::parse(&toks, file)?;
    let spelling = spellings(src, &toks);
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
        globals: HashMap::new(),
        global_syms: Vec::new(),
        located: Vec::new(),
        pou_names: Vec::new(),
        code_fns: Vec::new(),
        code_fbs: Vec::new(),
        string_lits: HashMap::new(),
    };
    let program = c.unit(&unit);
    // A program instantiated twice reports its body's errors once.
    let mut seen = HashSet::new();
    c.errors
        .retain(|e| seen.insert((e.pos.line, e.pos.col, e.message.clone())));
    match program {
        Ok(p) if c.errors.is_empty() => Ok(p),
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
        let mut out = String::with_capacity(msg.len());
        let mut parts = msg.split('\'');
        if let Some(first) = parts.next() {
            out.push_str(first);
        }
        for (i, part) in parts.enumerate() {
            out.push('\'');
            if i % 2 == 0 {
                out.push_str(self.spelling.get(part).map_or(part, String::as_str));
            } else {
                out.push_str(part);
            }
        }
        out
    }

    fn alloc(&mut self, n: u32, pos: Pos) -> R<u32> {
        let start = self.image.len() as u64;
        if start + n as u64 > MAX_SLOTS {
            return Err(self.e(
                pos,
                ErrorKind::Invalid,
                "program needs more than 16 Mi slots of memory",
            ));
        }
        self.image.resize((start + n as u64) as usize, 0);
        Ok(start as u32)
    }

    fn type_name(&self, t: &Type) -> String {
        match t {
            Type::Elem(e) => e.name().into(),
            Type::String(n) => format!("STRING[{n}]"),
            Type::Enum(id) => self.enums[*id as usize].name.clone(),
            Type::Subrange(e, l, h) => format!("{}({l}..{h})", e.name()),
            Type::Array(a) => format!("ARRAY OF {}", self.type_name(&a.elem)),
            Type::Struct(id) => self.structs[*id as usize].0.name.clone(),
            Type::Fb(id) => self.fbs[*id as usize].name.clone(),
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

    fn unit(&mut self, u: &'a ast::Unit) -> R<Program> {
        let mut seen: HashMap<String, Pos> = HashMap::new();
        let mut check_dup = |c: &Compiler, n: &Name| -> R<()> {
            if Elem::from_name(&n.text).is_some()
                || StdFb::from_name(&n.text).is_some()
                || n.text == "STRING"
            {
                return Err(c.e(
                    n.pos,
                    ErrorKind::Duplicate,
                    format!("'{}' is a standard name", n.text),
                ));
            }
            if let Some(p) = seen.insert(n.text.clone(), n.pos) {
                return Err(c.e(
                    n.pos,
                    ErrorKind::Duplicate,
                    format!("'{}' is already declared at line {}", n.text, p.line),
                ));
            }
            Ok(())
        };
        for t in &u.types {
            check_dup(self, &t.name)?;
            self.type_asts.insert(t.name.text.clone(), t);
        }
        let mut programs: Vec<&'a ast::Pou> = Vec::new();
        for p in &u.pous {
            check_dup(self, &p.name)?;
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
        for t in &u.types {
            if let Err(e) = self.named_type(&t.name) {
                self.errors.push(e);
            }
        }
        let fb_names: Vec<Name> = u
            .pous
            .iter()
            .filter(|p| p.kind == PouKind::FunctionBlock)
            .map(|p| p.name.clone())
            .collect();
        for n in &fb_names {
            if let Err(e) = self.fb_type(n) {
                self.errors.push(e);
            }
        }
        let fn_names: Vec<Name> = u
            .pous
            .iter()
            .filter(|p| p.kind == PouKind::Function)
            .map(|p| p.name.clone())
            .collect();
        for n in &fn_names {
            if let Err(e) = self.func(n) {
                self.errors.push(e);
            }
        }
        // Globals: top level and of the configurations.
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
            };
            for d in &b.decls {
                if let Err(e) = self.declare_global(b, d, &scope) {
                    self.errors.push(e);
                }
            }
        }
        if !self.errors.is_empty() {
            return Err(self.errors.remove(0));
        }
        // Bodies of function blocks and functions.
        for n in &fb_names {
            if let Err(e) = self.fb_body(n) {
                self.errors.push(e);
            }
        }
        for n in &fn_names {
            if let Err(e) = self.fn_body(n) {
                self.errors.push(e);
            }
        }
        self.check_recursion(&fn_names)?;

        // Program instances and tasks.
        let prog_by_name: HashMap<&str, &'a ast::Pou> = programs
            .iter()
            .map(|p| (p.name.text.as_str(), *p))
            .collect();
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
                    let interval = match &t.interval {
                        Some(e) => {
                            let ns = self.const_time(e)?;
                            if ns <= 0 {
                                return Err(self.e(
                                    e.pos(),
                                    ErrorKind::Invalid,
                                    "INTERVAL must be positive",
                                ));
                            }
                            Some(Duration::from_nanos(ns as u64))
                        }
                        None => None,
                    };
                    if let Some(s) = &t.single {
                        return Err(self.e(
                            s.pos(),
                            ErrorKind::Invalid,
                            "event tasks (SINGLE) are not supported; use INTERVAL",
                        ));
                    }
                    let priority = match &t.priority {
                        Some(e) => {
                            let v = self.const_int(e)?;
                            u32::try_from(v).map_err(|_| {
                                self.e(e.pos(), ErrorKind::Invalid, "PRIORITY must be 0 or more")
                            })?
                        }
                        None => 0,
                    };
                    tasks.push(TaskDesc {
                        name: t.name.text.clone(),
                        interval,
                        priority,
                        programs: Vec::new(),
                        program_ids: Vec::new(),
                    });
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
                        Some(tn) => {
                            let Some(t) =
                                tasks[first_task..].iter_mut().find(|t| t.name == tn.text)
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
        } else {
            for p in &programs {
                let idx = instances.len();
                instances.push(self.program_instance(p, &p.name.text)?);
                default_task.push(idx);
            }
        }
        // A PROGRAM the configuration does not instantiate is still checked: it gets an
        // instance of its own name that no task runs.
        for p in &programs {
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
                programs: default_task
                    .iter()
                    .map(|i| instances[*i].name.clone())
                    .collect(),
                program_ids: default_task,
            });
        }
        tasks.sort_by_key(|t| t.priority);
        if !self.errors.is_empty() {
            return Err(self.errors.remove(0));
        }
        let mut sizes = [0usize; 3];
        for l in &self.located {
            let a = area_index(l.at.area);
            sizes[a] = sizes[a].max(l.at.byte_offset() + l.at.byte_len());
        }
        let functions = self
            .code_fns
            .drain(..)
            .map(|f| f.expect("every function body compiled"))
            .collect();
        let fbs = self
            .code_fbs
            .drain(..)
            .map(|f| f.expect("every function block body compiled"))
            .collect();
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
            fbs: self
                .fbs
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
                .collect(),
            located: std::mem::take(&mut self.located),
            image_sizes: sizes,
            pou_count: u.pous.len(),
        })
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
                let pos = names
                    .iter()
                    .find(|n| &n.text == name)
                    .map_or(Pos::default(), |n| n.pos);
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

    // ---------------------------------------------------------------- types

    fn named_type(&mut self, n: &Name) -> R<(Type, Option<Vec<u64>>)> {
        if let Some(t) = self.named.get(&n.text) {
            return Ok(t.clone());
        }
        if let Some(e) = Elem::from_name(&n.text) {
            return Ok((Type::Elem(e), None));
        }
        if n.text == "STRING" {
            return Ok((Type::String(DEFAULT_STRING_LEN), None));
        }
        if let Some(id) = self.fb_id(n)? {
            return Ok((Type::Fb(id), None));
        }
        let Some(decl) = self.type_asts.get(&n.text).copied() else {
            return Err(self.e(
                n.pos,
                ErrorKind::Undeclared,
                format!("unknown type '{}'", n.text),
            ));
        };
        if !self.resolving.insert(n.text.clone()) {
            return Err(self.e(
                n.pos,
                ErrorKind::Invalid,
                format!("type '{}' is defined through itself", n.text),
            ));
        }
        let scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::Program,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
        };
        let r = self.type_spec(&decl.spec, Some(&decl.name.text), &scope);
        self.resolving.remove(&n.text);
        let (ty, mut tpl) = r?;
        if let Some(init) = &decl.init {
            let mut t = tpl.unwrap_or_else(|| self.template(&ty));
            self.apply_init(&ty, init, &mut t, 0, &scope)?;
            tpl = Some(t);
        }
        self.named.insert(n.text.clone(), (ty.clone(), tpl.clone()));
        Ok((ty, tpl))
    }

    fn type_spec(
        &mut self,
        spec: &TypeSpec,
        name: Option<&str>,
        scope: &Scope,
    ) -> R<(Type, Option<Vec<u64>>)> {
        match spec {
            TypeSpec::Named(n) => self.named_type(n),
            TypeSpec::String { len, pos } => {
                let n = match len {
                    Some(e) => self.const_int_in(e, scope)?,
                    None => DEFAULT_STRING_LEN as i128,
                };
                if n < 1 || n > MAX_STRING_LEN as i128 {
                    return Err(self.e(
                        *pos,
                        ErrorKind::Invalid,
                        format!("STRING length must be 1..{MAX_STRING_LEN}"),
                    ));
                }
                Ok((Type::String(n as u16), None))
            }
            TypeSpec::Array { dims, elem, pos } => {
                let mut bounds = Vec::new();
                for (lo, hi) in dims {
                    let l = self.const_int_in(lo, scope)?;
                    let h = self.const_int_in(hi, scope)?;
                    if h < l
                        || h - l >= MAX_SLOTS as i128
                        || l < i64::MIN as i128 / 2
                        || h > i64::MAX as i128 / 2
                    {
                        return Err(self.e(
                            lo.pos(),
                            ErrorKind::Invalid,
                            format!("array bounds {l}..{h} are empty or too large"),
                        ));
                    }
                    bounds.push((l as i64, h as i64));
                }
                let (et, etpl) = self.type_spec(elem, None, scope)?;
                let elem_size = size_of(self, &et);
                let count: u64 = bounds.iter().map(|(l, h)| (h - l + 1) as u64).product();
                if count.saturating_mul(elem_size as u64) > MAX_SLOTS {
                    return Err(self.e(*pos, ErrorKind::Invalid, "array is too large"));
                }
                let at = Type::Array(Arc::new(ArrayType {
                    dims: bounds,
                    elem: et,
                    elem_size,
                }));
                let tpl = etpl.map(|t| t.repeat(count as usize));
                Ok((at, tpl))
            }
            TypeSpec::Struct { fields, pos } => {
                let mut fs: Vec<Field> = Vec::new();
                let mut off = 0u32;
                let mut inits: Vec<FieldInit> = Vec::new();
                for d in fields {
                    let (t, tpl) = self.type_spec(&d.ty, None, scope)?;
                    for n in &d.names {
                        if fs.iter().any(|f| f.name == n.text) {
                            return Err(self.e(
                                n.pos,
                                ErrorKind::Duplicate,
                                format!("field '{}' declared twice", n.text),
                            ));
                        }
                        fs.push(Field {
                            name: n.text.clone(),
                            ty: t.clone(),
                            offset: off,
                        });
                        inits.push((off, t.clone(), tpl.clone(), d.init.as_ref()));
                        off = off.saturating_add(size_of(self, &t));
                    }
                }
                if off as u64 > MAX_SLOTS {
                    return Err(self.e(*pos, ErrorKind::Invalid, "structure is too large"));
                }
                let mut tpl = vec![0u64; off as usize];
                for (o, t, ttpl, init) in inits {
                    let sub = ttpl.unwrap_or_else(|| self.template(&t));
                    tpl[o as usize..o as usize + sub.len()].copy_from_slice(&sub);
                    if let Some(i) = init {
                        self.apply_init(&t, i, &mut tpl, o as usize, scope)?;
                    }
                }
                let id = self.structs.len() as u32;
                let sname = name.map_or_else(|| format!("STRUCT#{id}"), str::to_string);
                self.structs.push((
                    StructType {
                        name: sname,
                        fields: fs,
                        size: off,
                    },
                    tpl,
                ));
                Ok((Type::Struct(id), None))
            }
            TypeSpec::Enum { values, base, pos } => {
                if let Some(b) = base {
                    let ok = Elem::from_name(&b.text).is_some_and(|e| e.is_int() || e.is_bit());
                    if !ok {
                        return Err(self.e(
                            b.pos,
                            ErrorKind::TypeMismatch,
                            "an enumeration's base type must be an integer type",
                        ));
                    }
                }
                let id = self.enums.len() as u32;
                let mut vals: Vec<(String, i64)> = Vec::new();
                let mut next = 0i64;
                for (n, v) in values {
                    let val = match v {
                        Some(e) => self.const_int_in(e, scope)? as i64,
                        None => next,
                    };
                    if vals.iter().any(|(x, _)| x == &n.text) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::Duplicate,
                            format!("enumeration value '{}' declared twice", n.text),
                        ));
                    }
                    vals.push((n.text.clone(), val));
                    next = val.wrapping_add(1);
                    self.enum_values
                        .entry(n.text.clone())
                        .or_default()
                        .push((id, val));
                }
                if vals.is_empty() {
                    return Err(self.e(*pos, ErrorKind::Invalid, "empty enumeration"));
                }
                let ename = name.map_or_else(|| format!("ENUM#{id}"), str::to_string);
                self.enums.push(EnumType {
                    name: ename,
                    values: vals,
                });
                Ok((Type::Enum(id), None))
            }
            TypeSpec::Subrange { base, low, high } => {
                let Some(e) = Elem::from_name(&base.text).filter(|e| e.is_int()) else {
                    return Err(self.e(
                        base.pos,
                        ErrorKind::TypeMismatch,
                        "a subrange needs an integer base type",
                    ));
                };
                let l = self.const_int_in(low, scope)?;
                let h = self.const_int_in(high, scope)?;
                let (tl, th) = e.int_range().unwrap_or((0, 0));
                if l > h || l < tl || h > th {
                    return Err(self.e(
                        low.pos(),
                        ErrorKind::Invalid,
                        format!("subrange {l}..{h} does not fit {}", e.name()),
                    ));
                }
                Ok((Type::Subrange(e, l as i64, h as i64), None))
            }
        }
    }

    /// Default initial slots of a type.
    fn template(&self, t: &Type) -> Vec<u64> {
        match t {
            Type::Elem(_) => vec![0],
            Type::String(n) => vec![0; string_slots(*n) as usize],
            Type::Enum(id) => vec![self.enums[*id as usize].values[0].1 as u64],
            Type::Subrange(_, l, h) => vec![if *l <= 0 && 0 <= *h { 0 } else { *l as u64 }],
            Type::Array(a) => {
                let e = self.template(&a.elem);
                e.repeat(a.len() as usize)
            }
            Type::Struct(id) => self.structs[*id as usize].1.clone(),
            Type::Fb(id) => self.fbs[*id as usize].template.clone(),
        }
    }

    /// Writes an initializer into `tpl` at `at`.
    fn apply_init(
        &mut self,
        t: &Type,
        init: &Init,
        tpl: &mut [u64],
        at: usize,
        scope: &Scope,
    ) -> R<()> {
        match (init, t) {
            (Init::Expr(e), _) if t.scalar().is_some() => {
                let te = self.const_value(e, scope)?;
                let v = self.coerce(te, t, e.pos())?;
                match v {
                    vm::Expr::Const(v) => {
                        if let Type::Subrange(_, l, h) = t {
                            let x = v as i64;
                            if x < *l || x > *h {
                                return Err(self.e(
                                    e.pos(),
                                    ErrorKind::TypeMismatch,
                                    format!("initial value {x} outside subrange {l}..{h}"),
                                ));
                            }
                        }
                        if let Some(s) = tpl.get_mut(at) {
                            *s = v;
                        }
                        Ok(())
                    }
                    _ => Err(self.e(
                        e.pos(),
                        ErrorKind::Invalid,
                        "initial value must be a constant",
                    )),
                }
            }
            (Init::Expr(AExpr::Lit(Literal::Str(s), _)), Type::String(cap)) => {
                let mut tmp = vec![0u64; string_slots(*cap) as usize];
                crate::strings::write(&mut tmp, 0, *cap, s);
                tpl[at..at + tmp.len()].copy_from_slice(&tmp);
                Ok(())
            }
            (Init::Array(items, pos), Type::Array(a)) => {
                let mut k = 0u64;
                let n = a.len();
                for (count, item) in items {
                    let reps = match count {
                        Some(c) => self.const_int_in(c, scope)?.max(0) as u64,
                        None => 1,
                    };
                    for _ in 0..reps {
                        if k >= n {
                            return Err(self.e(
                                *pos,
                                ErrorKind::Invalid,
                                format!("more than {n} initial values for the array"),
                            ));
                        }
                        if !matches!(item, Init::Array(v, _) if v.is_empty()) {
                            self.apply_init(
                                &a.elem,
                                item,
                                tpl,
                                at + (k * a.elem_size as u64) as usize,
                                scope,
                            )?;
                        }
                        k += 1;
                    }
                }
                Ok(())
            }
            (Init::Struct(items, _), Type::Struct(id)) => {
                let fields = self.structs[*id as usize].0.fields.clone();
                for (n, i) in items {
                    let Some(f) = fields.iter().find(|f| f.name == n.text) else {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::Undeclared,
                            format!("no field '{}'", n.text),
                        ));
                    };
                    self.apply_init(&f.ty, i, tpl, at + f.offset as usize, scope)?;
                }
                Ok(())
            }
            (Init::Struct(items, _), Type::Fb(id)) => {
                let members = self.fbs[*id as usize].members.clone();
                for (n, i) in items {
                    let Some(m) = members
                        .iter()
                        .find(|m| m.name == n.text && m.kind == VarKind::Input)
                    else {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::Undeclared,
                            format!("no input '{}'", n.text),
                        ));
                    };
                    self.apply_init(&m.ty, i, tpl, at + m.offset as usize, scope)?;
                }
                Ok(())
            }
            (Init::Expr(e), _) => Err(self.e(
                e.pos(),
                ErrorKind::TypeMismatch,
                format!("cannot initialise a {} with this value", self.type_name(t)),
            )),
            (Init::Array(_, p) | Init::Struct(_, p), _) => Err(self.e(
                *p,
                ErrorKind::TypeMismatch,
                format!(
                    "cannot initialise a {} with this initializer",
                    self.type_name(t)
                ),
            )),
        }
    }

    // ---------------------------------------------------------------- POU signatures

    fn fb_id(&mut self, n: &Name) -> R<Option<u32>> {
        match self.fb_by_name.get(&n.text) {
            Some(Lookup::Found(id)) => return Ok(Some(*id)),
            Some(Lookup::Busy) => {
                return Err(self.e(
                    n.pos,
                    ErrorKind::Invalid,
                    format!("function block '{}' contains itself", n.text),
                ));
            }
            _ => {}
        }
        if let Some(s) = StdFb::from_name(&n.text) {
            let members: Vec<Member> = s
                .members()
                .iter()
                .enumerate()
                .map(|(i, (name, e, d))| Member {
                    name: name.to_string(),
                    ty: Type::Elem(*e),
                    offset: i as u32,
                    kind: if *d == Dir::In {
                        VarKind::Input
                    } else {
                        VarKind::Output
                    },
                    constant: false,
                    retain: false,
                })
                .collect();
            let mut template = vec![0u64; s.size() as usize];
            s.init_hidden(&mut template);
            let id = self.fbs.len() as u32;
            self.fbs.push(FbInfo {
                name: s.name().into(),
                members,
                size: s.size(),
                template,
                std: Some(s),
                body: 0,
            });
            self.fb_by_name.insert(n.text.clone(), Lookup::Found(id));
            return Ok(Some(id));
        }
        if self.fb_asts.contains_key(&n.text) {
            return self.fb_type(n).map(Some);
        }
        Ok(None)
    }

    fn fb_type(&mut self, n: &Name) -> R<u32> {
        if let Some(Lookup::Found(id)) = self.fb_by_name.get(&n.text) {
            return Ok(*id);
        }
        let pou = self.fb_asts[&n.text];
        self.fb_by_name.insert(n.text.clone(), Lookup::Busy);
        let r = self.fb_layout(pou);
        match r {
            Ok(info) => {
                let id = self.fbs.len() as u32;
                self.fbs.push(info);
                self.fb_by_name.insert(n.text.clone(), Lookup::Found(id));
                Ok(id)
            }
            Err(e) => {
                self.fb_by_name.insert(n.text.clone(), Lookup::Missing);
                Err(e)
            }
        }
    }

    fn fb_layout(&mut self, pou: &'a ast::Pou) -> R<FbInfo> {
        let mut members: Vec<Member> = Vec::new();
        let mut off = 0u32;
        let mut template: Vec<u64> = Vec::new();
        let scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::FunctionBlock,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
        };
        for b in &pou.vars {
            if matches!(b.kind, VarKind::Global) {
                return Err(self.e(
                    pou.name.pos,
                    ErrorKind::Invalid,
                    "VAR_GLOBAL is not allowed inside a function block",
                ));
            }
            if b.kind == VarKind::External {
                continue;
            }
            for d in &b.decls {
                if let Some((_, p)) = d.at {
                    return Err(self.e(
                        p,
                        ErrorKind::Invalid,
                        "located variables belong in programs or VAR_GLOBAL",
                    ));
                }
                let (t, tpl) = self.type_spec(&d.ty, None, &scope)?;
                for n in &d.names {
                    if members.iter().any(|m| m.name == n.text) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::Duplicate,
                            format!("'{}' is already declared", n.text),
                        ));
                    }
                    let size = if b.kind == VarKind::InOut {
                        1
                    } else {
                        size_of(self, &t)
                    };
                    let mut sub = if b.kind == VarKind::InOut {
                        vec![0]
                    } else {
                        tpl.clone().unwrap_or_else(|| self.template(&t))
                    };
                    if let (Some(i), false) = (&d.init, b.kind == VarKind::InOut) {
                        self.apply_init(&t, i, &mut sub, 0, &scope)?;
                    }
                    template.extend_from_slice(&sub);
                    members.push(Member {
                        name: n.text.clone(),
                        ty: t.clone(),
                        offset: off,
                        kind: b.kind,
                        constant: b.constant,
                        retain: b.retain,
                    });
                    off = off.saturating_add(size);
                }
            }
        }
        if off as u64 > MAX_SLOTS {
            return Err(self.e(
                pou.name.pos,
                ErrorKind::Invalid,
                "function block is too large",
            ));
        }
        let body = self.code_fbs.len() as u32;
        self.code_fbs.push(None);
        Ok(FbInfo {
            name: pou.name.text.clone(),
            members,
            size: off,
            template,
            std: None,
            body,
        })
    }

    fn func_id(&mut self, n: &Name) -> R<Option<u32>> {
        match self.fn_by_name.get(&n.text) {
            Some(Lookup::Found(id)) => return Ok(Some(*id)),
            Some(Lookup::Busy) => return Ok(None),
            _ => {}
        }
        if self.fn_asts.contains_key(&n.text) {
            self.func(n).map(Some)
        } else {
            Ok(None)
        }
    }

    fn func(&mut self, n: &Name) -> R<u32> {
        if let Some(Lookup::Found(id)) = self.fn_by_name.get(&n.text) {
            return Ok(*id);
        }
        let pou = self.fn_asts[&n.text];
        self.fn_by_name.insert(n.text.clone(), Lookup::Busy);
        let scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::Function,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
        };
        let ret = match &pou.ret {
            Some(TypeSpec::Named(t)) if t.text == "VOID" => None,
            Some(spec) => Some(self.type_spec(spec, None, &scope)?.0),
            None => None,
        };
        if let Some(Type::Fb(_)) = ret {
            return Err(self.e(
                pou.name.pos,
                ErrorKind::Invalid,
                "a function cannot return a function block",
            ));
        }
        let start = self.image.len() as u32;
        let result = self.alloc(ret.as_ref().map_or(1, |t| size_of(self, t)), pou.name.pos)?;
        if let Some(t) = &ret {
            let tpl = self.template(t);
            self.image[result as usize..result as usize + tpl.len()].copy_from_slice(&tpl);
        }
        let mut locals: HashMap<String, VarInfo> = HashMap::new();
        let mut params: Vec<Member> = Vec::new();
        if let Some(t) = &ret {
            locals.insert(
                pou.name.text.clone(),
                VarInfo {
                    ty: t.clone(),
                    loc: Loc::Abs(result),
                    kind: VarKind::Output,
                    constant: false,
                    const_val: None,
                    input_area: false,
                },
            );
        }
        for b in &pou.vars {
            if matches!(b.kind, VarKind::Global) {
                return Err(self.e(
                    pou.name.pos,
                    ErrorKind::Invalid,
                    "VAR_GLOBAL is not allowed inside a function",
                ));
            }
            for d in &b.decls {
                if b.kind == VarKind::External {
                    for n in &d.names {
                        let g = self.external(n, d, &scope)?;
                        locals.insert(n.text.clone(), g);
                    }
                    continue;
                }
                if let Some((_, p)) = d.at {
                    return Err(self.e(
                        p,
                        ErrorKind::Invalid,
                        "located variables belong in programs or VAR_GLOBAL",
                    ));
                }
                let (t, tpl) = self.type_spec(&d.ty, None, &scope)?;
                for n in &d.names {
                    if locals.contains_key(&n.text) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::Duplicate,
                            format!("'{}' is already declared", n.text),
                        ));
                    }
                    let inout = b.kind == VarKind::InOut;
                    let size = if inout { 1 } else { size_of(self, &t) };
                    let a = self.alloc(size, n.pos)?;
                    if !inout {
                        let mut sub = tpl.clone().unwrap_or_else(|| self.template(&t));
                        if let Some(i) = &d.init {
                            self.apply_init(&t, i, &mut sub, 0, &scope)?;
                        }
                        self.image[a as usize..a as usize + sub.len()].copy_from_slice(&sub);
                    }
                    let const_val = if b.constant && t.scalar().is_some() {
                        Some(self.image[a as usize])
                    } else {
                        None
                    };
                    let loc = if inout { Loc::IndAbs(a) } else { Loc::Abs(a) };
                    locals.insert(
                        n.text.clone(),
                        VarInfo {
                            ty: t.clone(),
                            loc,
                            kind: b.kind,
                            constant: b.constant,
                            const_val,
                            input_area: false,
                        },
                    );
                    if matches!(b.kind, VarKind::Input | VarKind::Output | VarKind::InOut) {
                        params.push(Member {
                            name: n.text.clone(),
                            ty: t.clone(),
                            offset: a,
                            kind: b.kind,
                            constant: false,
                            retain: false,
                        });
                    }
                }
            }
        }
        let end = self.image.len() as u32;
        let pou_id = self.new_pou_name(&pou.name.text);
        let id = self.funcs.len() as u32;
        self.funcs.push(FuncInfo {
            name: pou.name.text.clone(),
            pou: pou_id,
            ret,
            result,
            params,
            locals,
            frame: (start, end - start),
        });
        self.fn_calls.push(Vec::new());
        self.code_fns.push(None);
        self.fn_by_name.insert(n.text.clone(), Lookup::Found(id));
        Ok(id)
    }

    fn external(&mut self, n: &Name, d: &ast::VarDecl, scope: &Scope) -> R<VarInfo> {
        let Some(g) = self.globals.get(&n.text).cloned() else {
            return Err(self.e(
                n.pos,
                ErrorKind::Undeclared,
                format!("VAR_EXTERNAL '{}' has no VAR_GLOBAL", n.text),
            ));
        };
        let (t, _) = self.type_spec(&d.ty, None, scope)?;
        if t != g.ty {
            return Err(self.e(
                n.pos,
                ErrorKind::TypeMismatch,
                format!(
                    "VAR_EXTERNAL '{}' is {} but the global is {}",
                    n.text,
                    self.type_name(&t),
                    self.type_name(&g.ty)
                ),
            ));
        }
        Ok(g)
    }

    // ---------------------------------------------------------------- declarations

    fn declare_global(&mut self, b: &ast::VarBlock, d: &ast::VarDecl, scope: &Scope) -> R<()> {
        if b.kind != VarKind::Global {
            return Err(self.e(
                d.names[0].pos,
                ErrorKind::Invalid,
                "only VAR_GLOBAL is allowed here",
            ));
        }
        for n in &d.names {
            if self.globals.contains_key(&n.text) {
                return Err(self.e(
                    n.pos,
                    ErrorKind::Duplicate,
                    format!("global '{}' is already declared", n.text),
                ));
            }
            let (info, sym) = self.declare_static(n, d, b, scope, "")?;
            self.globals.insert(n.text.clone(), info);
            self.global_syms.push(sym);
        }
        Ok(())
    }

    /// Allocates a variable at an absolute address (globals, program variables).
    fn declare_static(
        &mut self,
        n: &Name,
        d: &ast::VarDecl,
        b: &ast::VarBlock,
        scope: &Scope,
        prefix: &str,
    ) -> R<(VarInfo, Symbol)> {
        let (t, tpl) = self.type_spec(&d.ty, None, scope)?;
        let size = size_of(self, &t);
        let a = self.alloc(size, n.pos)?;
        let mut sub = tpl.unwrap_or_else(|| self.template(&t));
        if let Some(i) = &d.init {
            self.apply_init(&t, i, &mut sub, 0, scope)?;
        }
        self.image[a as usize..a as usize + sub.len()].copy_from_slice(&sub);
        let mut input_area = false;
        if let Some((at, p)) = d.at {
            let Some(e) = t.elem() else {
                return Err(self.e(
                    p,
                    ErrorKind::TypeMismatch,
                    "a located variable must be of an elementary type",
                ));
            };
            let ok = match at.size {
                AddrSize::Bit => e == Elem::Bool,
                AddrSize::Byte => matches!(e, Elem::Byte | Elem::SInt | Elem::USInt),
                AddrSize::Word => matches!(e, Elem::Word | Elem::Int | Elem::UInt),
                AddrSize::Double => {
                    matches!(e, Elem::DWord | Elem::DInt | Elem::UDInt | Elem::Real)
                }
                AddrSize::Long => matches!(
                    e,
                    Elem::LWord | Elem::LInt | Elem::ULInt | Elem::LReal | Elem::Time
                ),
            };
            if !ok {
                return Err(self.e(
                    p,
                    ErrorKind::TypeMismatch,
                    format!("{} does not fit the address {at}", e.name()),
                ));
            }
            if self.located.iter().any(|l| l.at == at) && at.area != Area::Memory {
                return Err(self.e(
                    p,
                    ErrorKind::Duplicate,
                    format!("address {at} is already used"),
                ));
            }
            input_area = at.area == Area::Input;
            self.located.push(Located {
                at,
                slot: a,
                elem: e,
            });
        }
        let const_val = if b.constant && t.scalar().is_some() {
            Some(self.image[a as usize])
        } else {
            None
        };
        let info = VarInfo {
            ty: t.clone(),
            loc: Loc::Abs(a),
            kind: b.kind,
            constant: b.constant,
            const_val,
            input_area,
        };
        let sym = Symbol {
            name: format!("{prefix}{}", n.text),
            ty: t,
            addr: a,
            kind: b.kind,
            retain: b.retain,
            indirect: false,
        };
        Ok((info, sym))
    }

    fn program_instance(&mut self, pou: &'a ast::Pou, inst: &str) -> R<ProgramInstance> {
        let pou_id = self.new_pou_name(&pou.name.text);
        let mut scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::Program,
            pou: pou_id,
            loops: 0,
            calls: Vec::new(),
        };
        let mut syms = Vec::new();
        for b in &pou.vars {
            for d in &b.decls {
                for n in &d.names {
                    if scope.vars.contains_key(&n.text) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::Duplicate,
                            format!("'{}' is already declared", n.text),
                        ));
                    }
                    match b.kind {
                        VarKind::External => {
                            let g = self.external(n, d, &scope)?;
                            scope.vars.insert(n.text.clone(), g);
                        }
                        VarKind::InOut => {
                            return Err(self.e(
                                n.pos,
                                ErrorKind::Invalid,
                                "VAR_IN_OUT is not allowed in a PROGRAM",
                            ));
                        }
                        _ => {
                            let (info, sym) = self.declare_static(n, d, b, &scope, "")?;
                            scope.vars.insert(n.text.clone(), info);
                            syms.push(sym);
                        }
                    }
                }
            }
        }
        let body = self.block(&pou.body, &mut scope)?;
        Ok(ProgramInstance {
            name: inst.to_string(),
            pou_type: pou.name.text.clone(),
            pou: pou_id,
            vars: syms,
            body,
        })
    }

    fn fb_body(&mut self, n: &Name) -> R<()> {
        let id = self.fb_type(n)?;
        let pou = self.fb_asts[&n.text];
        let pou_id = self.new_pou_name(&pou.name.text);
        let members = self.fbs[id as usize].members.clone();
        let mut scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::FunctionBlock,
            pou: pou_id,
            loops: 0,
            calls: Vec::new(),
        };
        for m in &members {
            let loc = if m.kind == VarKind::InOut {
                Loc::IndRel(m.offset)
            } else {
                Loc::Rel(m.offset)
            };
            let const_val = if m.constant && m.ty.scalar().is_some() {
                self.fbs[id as usize]
                    .template
                    .get(m.offset as usize)
                    .copied()
            } else {
                None
            };
            scope.vars.insert(
                m.name.clone(),
                VarInfo {
                    ty: m.ty.clone(),
                    loc,
                    kind: m.kind,
                    constant: m.constant,
                    const_val,
                    input_area: false,
                },
            );
        }
        let empty = Scope {
            vars: HashMap::new(),
            kind: PouKind::FunctionBlock,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
        };
        for b in pou.vars.iter().filter(|b| b.kind == VarKind::External) {
            for d in &b.decls {
                for nm in &d.names {
                    let g = self.external(nm, d, &empty)?;
                    scope.vars.insert(nm.text.clone(), g);
                }
            }
        }
        let stmts = self.block(&pou.body, &mut scope)?;
        // VAR_TEMP members are re-initialised on every call.
        let temps: Vec<&Member> = members.iter().filter(|m| m.kind == VarKind::Temp).collect();
        let reinit = match (temps.first(), temps.last()) {
            (Some(f), Some(l)) => {
                let start = f.offset;
                let end = l.offset + size_of(self, &l.ty);
                let tpl = &self.fbs[id as usize].template;
                Some((
                    start,
                    tpl[start as usize..end as usize]
                        .to_vec()
                        .into_boxed_slice(),
                ))
            }
            _ => None,
        };
        let body_id = self.fbs[id as usize].body;
        self.code_fbs[body_id as usize] = Some(vm::Body {
            pou: pou_id,
            reinit,
            stmts,
        });
        Ok(())
    }

    fn fn_body(&mut self, n: &Name) -> R<()> {
        let id = self.func(n)?;
        let pou = self.fn_asts[&n.text];
        let (vars, pou_id, frame, result, aggregate) = {
            let f = &self.funcs[id as usize];
            (
                f.locals.clone(),
                f.pou,
                f.frame,
                f.result,
                f.ret.as_ref().is_some_and(|t| t.scalar().is_none()),
            )
        };
        let mut scope = Scope {
            vars,
            kind: PouKind::Function,
            pou: pou_id,
            loops: 0,
            calls: Vec::new(),
        };
        let stmts = self.block(&pou.body, &mut scope)?;
        self.fn_calls[id as usize] = std::mem::take(&mut scope.calls);
        let values = self.image[frame.0 as usize..(frame.0 + frame.1) as usize]
            .to_vec()
            .into_boxed_slice();
        self.code_fns[id as usize] = Some(vm::Function {
            body: vm::Body {
                pou: pou_id,
                reinit: Some((frame.0, values)),
                stmts,
            },
            result,
            aggregate,
        });
        Ok(())
    }

    // ---------------------------------------------------------------- statements

    fn block(&mut self, stmts: &[ast::Stmt], sc: &mut Scope) -> R<Block> {
        let mut out = Vec::with_capacity(stmts.len());
        for s in stmts {
            match self.stmt(s, sc) {
                Ok(Some(s)) => out.push(s),
                Ok(None) => {}
                Err(e) => self.errors.push(e),
            }
        }
        Ok(out.into_boxed_slice())
    }

    fn cond(&mut self, e: &AExpr, sc: &mut Scope) -> R<vm::Expr> {
        let te = self.expr(e, sc, Some(&Type::BOOL))?;
        self.coerce(te, &Type::BOOL, e.pos())
    }

    fn stmt(&mut self, s: &ast::Stmt, sc: &mut Scope) -> R<Option<Stmt>> {
        let (line, kind) = match s {
            ast::Stmt::Empty => return Ok(None),
            ast::Stmt::Assign(target, value, pos) => {
                (pos.line, self.assign(target, value, sc, *pos)?)
            }
            ast::Stmt::Call(target, args, pos) => {
                (pos.line, self.call_stmt(target, args, sc, *pos)?)
            }
            ast::Stmt::If(branches, els, pos) => {
                let mut bs = Vec::new();
                for (c, b) in branches {
                    let c = self.cond(c, sc)?;
                    bs.push((c, self.block(b, sc)?));
                }
                (
                    pos.line,
                    StmtKind::If(bs.into_boxed_slice(), self.block(els, sc)?),
                )
            }
            ast::Stmt::Case(sel, arms, els, pos) => {
                let te = self.expr(sel, sc, None)?;
                let sel_ty = match &te.ty {
                    Ty::T(t)
                        if t.scalar().is_some_and(|e| {
                            e.int_kind().is_some() && e != Elem::Time && e != Elem::Bool
                        }) =>
                    {
                        t.clone()
                    }
                    Ty::AnyInt(_) => Type::Elem(Elem::DInt),
                    _ => {
                        return Err(self.e(
                            sel.pos(),
                            ErrorKind::TypeMismatch,
                            "CASE needs an integer or enumeration selector",
                        ));
                    }
                };
                let signed = matches!(sel_ty, Type::Enum(_))
                    || sel_ty.scalar().is_some_and(|e| ik(e).signed());
                let selector = self.coerce(te, &sel_ty, sel.pos())?;
                let mut out = Vec::new();
                for arm in arms {
                    let mut ranges = Vec::new();
                    for (lo, hi) in &arm.labels {
                        let l = self.case_label(lo, &sel_ty, sc)?;
                        let h = match hi {
                            Some(h) => self.case_label(h, &sel_ty, sc)?,
                            None => l,
                        };
                        if h < l {
                            return Err(self.e(lo.pos(), ErrorKind::Invalid, "empty CASE range"));
                        }
                        ranges.push((l, h));
                    }
                    out.push(CaseArm {
                        ranges: ranges.into_boxed_slice(),
                        body: self.block(&arm.body, sc)?,
                    });
                }
                (
                    pos.line,
                    StmtKind::Case {
                        selector,
                        signed,
                        arms: out.into_boxed_slice(),
                        default: self.block(els, sc)?,
                    },
                )
            }
            ast::Stmt::For {
                var,
                from,
                to,
                by,
                body,
                pos,
            } => {
                let a = Access {
                    root: var.clone(),
                    parts: Vec::new(),
                };
                let lv = self.access(&a, sc)?;
                self.check_writable(&lv, var.pos)?;
                let Some(e) = lv.ty.elem().filter(|e| e.is_int()) else {
                    return Err(self.e(
                        var.pos,
                        ErrorKind::TypeMismatch,
                        "FOR needs an integer control variable",
                    ));
                };
                let t = Type::Elem(e);
                let f = self.expr(from, sc, Some(&t))?;
                let from_e = self.coerce(f, &t, from.pos())?;
                let tt = self.expr(to, sc, Some(&t))?;
                let to_e = self.coerce(tt, &t, to.pos())?;
                let by_e = match by {
                    Some(b) => {
                        let te = self.expr(b, sc, Some(&t))?;
                        self.coerce(te, &t, b.pos())?
                    }
                    None => vm::Expr::Const(1),
                };
                sc.loops += 1;
                let body = self.block(body, sc);
                sc.loops -= 1;
                let var_place = self.place(lv);
                (
                    pos.line,
                    StmtKind::For(Box::new(ForLoop {
                        var: var_place,
                        kind: ik(e),
                        from: from_e,
                        to: to_e,
                        by: by_e,
                        body: body?,
                    })),
                )
            }
            ast::Stmt::While(c, body, pos) => {
                let c = self.cond(c, sc)?;
                sc.loops += 1;
                let b = self.block(body, sc);
                sc.loops -= 1;
                (pos.line, StmtKind::While(c, b?))
            }
            ast::Stmt::Repeat(body, c, pos) => {
                sc.loops += 1;
                let b = self.block(body, sc);
                sc.loops -= 1;
                let c = self.cond(c, sc)?;
                (pos.line, StmtKind::Repeat(b?, c))
            }
            ast::Stmt::Exit(pos) | ast::Stmt::Continue(pos) => {
                if sc.loops == 0 {
                    return Err(self.e(
                        *pos,
                        ErrorKind::Invalid,
                        "EXIT and CONTINUE belong inside a loop",
                    ));
                }
                (
                    pos.line,
                    if matches!(s, ast::Stmt::Exit(_)) {
                        StmtKind::Exit
                    } else {
                        StmtKind::Continue
                    },
                )
            }
            ast::Stmt::Return(pos) => (pos.line, StmtKind::Return),
        };
        Ok(Some(Stmt { line, kind }))
    }

    fn case_label(&mut self, e: &AExpr, t: &Type, sc: &mut Scope) -> R<i64> {
        let te = self.expr(e, sc, Some(t))?;
        match self.coerce(te, t, e.pos())? {
            vm::Expr::Const(v) => Ok(v as i64),
            _ => Err(self.e(e.pos(), ErrorKind::Invalid, "CASE labels must be constants")),
        }
    }

    fn store_kind(&self, t: &Type) -> Store {
        match t {
            Type::Subrange(_, l, h) => Store::Range(*l, *h),
            Type::String(n) => Store::String(*n),
            t if t.scalar().is_some() => Store::Scalar,
            t => Store::Block(size_of(self, t)),
        }
    }

    fn assign(&mut self, target: &Access, value: &AExpr, sc: &mut Scope, pos: Pos) -> R<StmtKind> {
        let lv = self.access(target, sc)?;
        self.check_writable(&lv, target.root.pos)?;
        if let Type::Fb(_) = lv.ty {
            return Err(self.e(
                pos,
                ErrorKind::TypeMismatch,
                "function block instances cannot be assigned",
            ));
        }
        let te = self.expr(value, sc, Some(&lv.ty))?;
        if let Some(bit) = lv.bit {
            let v = self.coerce(te, &Type::BOOL, value.pos())?;
            let p = self.place(lv);
            return Ok(StmtKind::StoreBit(p, bit, v));
        }
        let ty = lv.ty.clone();
        let v = self.coerce(te, &ty, value.pos())?;
        if let (Type::Subrange(_, l, h), vm::Expr::Const(c)) = (&ty, &v) {
            let x = *c as i64;
            if x < *l || x > *h {
                return Err(self.e(
                    value.pos(),
                    ErrorKind::TypeMismatch,
                    format!("{x} is outside the subrange {l}..{h}"),
                ));
            }
        }
        let st = self.store_kind(&ty);
        let p = self.place(lv);
        Ok(StmtKind::Store(p, v, st))
    }

    fn check_writable(&self, lv: &Lv, pos: Pos) -> R<()> {
        match &lv.readonly {
            None => Ok(()),
            Some((k, m)) => Err(self.e(pos, *k, m.clone())),
        }
    }

    // ---------------------------------------------------------------- variable access

    fn lookup(&mut self, n: &Name, sc: &Scope) -> Option<VarInfo> {
        if let Some(v) = sc.vars.get(&n.text) {
            return Some(v.clone());
        }
        self.globals.get(&n.text).cloned()
    }

    fn access(&mut self, a: &Access, sc: &mut Scope) -> R<Lv> {
        if a.root.text.starts_with('%') && self.lookup(&a.root, sc).is_none() {
            let toks = crate::lexer::tokenize(&a.root.text, self.file)?;
            if let Some(crate::lexer::Tok::Direct(d)) = toks.first().map(|t| &t.kind) {
                self.direct_var(d, a.root.pos)?;
            }
        }
        let Some(v) = self.lookup(&a.root, sc) else {
            return Err(self.e(
                a.root.pos,
                ErrorKind::Undeclared,
                format!("'{}' is not declared", a.root.text),
            ));
        };
        let (base, indirect) = match v.loc {
            Loc::Abs(x) => (Base::Abs(x), false),
            Loc::Rel(x) => (Base::Rel(x), false),
            Loc::IndAbs(x) => (Base::Abs(x), true),
            Loc::IndRel(x) => (Base::Rel(x), true),
        };
        let readonly = if v.constant {
            Some((
                ErrorKind::AssignToConstant,
                format!("'{}' is a CONSTANT", a.root.text),
            ))
        } else if v.kind == VarKind::Input {
            Some((
                ErrorKind::AssignToInput,
                format!("'{}' is an input of this POU", a.root.text),
            ))
        } else if v.input_area {
            Some((
                ErrorKind::AssignToInput,
                format!("'{}' is located in the input image (%I)", a.root.text),
            ))
        } else {
            None
        };
        let mut lv = Lv {
            ty: v.ty.clone(),
            base,
            indirect,
            offset: 0,
            steps: Vec::new(),
            bit: None,
            readonly,
            const_val: v.const_val,
        };
        for p in &a.parts {
            if lv.bit.is_some() {
                return Err(self.e(
                    a.root.pos,
                    ErrorKind::Invalid,
                    "nothing can follow a bit access",
                ));
            }
            lv.const_val = None;
            match p {
                Part::Field(f) => match lv.ty.clone() {
                    Type::Struct(id) => {
                        let st = &self.structs[id as usize].0;
                        let Some(field) = st.fields.iter().find(|x| x.name == f.text) else {
                            return Err(self.e(
                                f.pos,
                                ErrorKind::Undeclared,
                                format!("{} has no field '{}'", st.name, f.text),
                            ));
                        };
                        lv.offset += field.offset;
                        lv.ty = field.ty.clone();
                    }
                    Type::Fb(id) => {
                        let fb = &self.fbs[id as usize];
                        let Some(m) = fb.members.iter().find(|x| x.name == f.text).cloned() else {
                            return Err(self.e(
                                f.pos,
                                ErrorKind::Undeclared,
                                format!("{} has no member '{}'", fb.name, f.text),
                            ));
                        };
                        if !matches!(m.kind, VarKind::Input | VarKind::Output | VarKind::InOut) {
                            return Err(self.e(
                                f.pos,
                                ErrorKind::Invalid,
                                format!("'{}' is internal to {}", f.text, fb.name),
                            ));
                        }
                        if m.kind == VarKind::InOut {
                            return Err(self.e(
                                f.pos,
                                ErrorKind::Invalid,
                                "VAR_IN_OUT members cannot be accessed from outside",
                            ));
                        }
                        if m.kind == VarKind::Output && lv.readonly.is_none() {
                            lv.readonly = Some((
                                ErrorKind::Invalid,
                                format!(
                                    "output '{}' of {} can only be written by the block",
                                    f.text, fb.name
                                ),
                            ));
                        }
                        lv.offset += m.offset;
                        lv.ty = m.ty.clone();
                    }
                    _ => {
                        return Err(self.e(
                            f.pos,
                            ErrorKind::TypeMismatch,
                            format!("'{}' is not a structure or function block", a.root.text),
                        ));
                    }
                },
                Part::Index(idx, pos) => {
                    let Type::Array(at) = lv.ty.clone() else {
                        return Err(self.e(
                            *pos,
                            ErrorKind::TypeMismatch,
                            format!("'{}' is not an array", a.root.text),
                        ));
                    };
                    if idx.len() != at.dims.len() {
                        return Err(self.e(
                            *pos,
                            ErrorKind::WrongArgument,
                            format!(
                                "array has {} dimensions, {} indices given",
                                at.dims.len(),
                                idx.len()
                            ),
                        ));
                    }
                    // Row-major strides.
                    let mut stride = at.elem_size as u64;
                    let mut strides = vec![0u64; at.dims.len()];
                    for (k, (l, h)) in at.dims.iter().enumerate().rev() {
                        strides[k] = stride;
                        stride *= (h - l + 1) as u64;
                    }
                    for (k, ie) in idx.iter().enumerate() {
                        let (lo, hi) = at.dims[k];
                        let te = self.expr(ie, sc, None)?;
                        let ok = match &te.ty {
                            Ty::AnyInt(_) => true,
                            Ty::T(t) => t.elem().is_some_and(|e| e.is_int()),
                            Ty::AnyReal(_) => false,
                        };
                        if !ok {
                            return Err(self.e(
                                ie.pos(),
                                ErrorKind::TypeMismatch,
                                format!(
                                    "array index must be an integer, not {}",
                                    self.ty_name(&te.ty)
                                ),
                            ));
                        }
                        let ity = match &te.ty {
                            Ty::T(t) => t.clone(),
                            _ => Type::Elem(Elem::LInt),
                        };
                        let e = self.coerce(te, &ity, ie.pos())?;
                        if let vm::Expr::Const(c) = e {
                            let i = if ity.elem().is_some_and(|e| ik(e).signed()) {
                                c as i64
                            } else {
                                c.min(i64::MAX as u64) as i64
                            };
                            if i < lo || i > hi {
                                return Err(self.e(
                                    ie.pos(),
                                    ErrorKind::Invalid,
                                    format!("index {i} is outside {lo}..{hi}"),
                                ));
                            }
                            lv.offset += ((i - lo) as u64 * strides[k]) as u32;
                        } else {
                            lv.steps.push(IndexStep {
                                index: e,
                                low: lo,
                                len: (hi - lo + 1) as u64,
                                stride: strides[k] as u32,
                            });
                        }
                    }
                    lv.ty = at.elem.clone();
                }
                Part::Bit(b, pos) => {
                    let Some(e) = lv
                        .ty
                        .elem()
                        .filter(|e| e.int_kind().is_some() && *e != Elem::Bool && *e != Elem::Time)
                    else {
                        return Err(self.e(
                            *pos,
                            ErrorKind::TypeMismatch,
                            "bit access needs an integer or bit-string variable",
                        ));
                    };
                    if *b as u32 >= e.bits() {
                        return Err(self.e(
                            *pos,
                            ErrorKind::Invalid,
                            format!("{} has no bit {b}", e.name()),
                        ));
                    }
                    lv.bit = Some(*b);
                }
            }
        }
        Ok(lv)
    }

    fn place(&self, lv: Lv) -> Place {
        if lv.steps.is_empty() && !lv.indirect {
            match lv.base {
                Base::Abs(a) => Place::Abs(a + lv.offset),
                Base::Rel(o) => Place::Rel(o + lv.offset),
            }
        } else {
            Place::Dyn(Box::new(DynPlace {
                base: lv.base,
                indirect: lv.indirect,
                offset: lv.offset,
                steps: lv.steps.into_boxed_slice(),
            }))
        }
    }

    fn load(&self, lv: Lv) -> TE {
        if let Some(c) = lv.const_val {
            return TE {
                ty: Ty::T(lv.ty),
                e: vm::Expr::Const(c),
            };
        }
        let ty = lv.ty.clone();
        let bit = lv.bit;
        let scalar = ty.scalar().is_some();
        let p = self.place(lv);
        let e = if !scalar {
            vm::Expr::AddrOf(p)
        } else {
            match p {
                Place::Abs(a) => vm::Expr::LoadAbs(a),
                Place::Rel(o) => vm::Expr::LoadRel(o),
                Place::Dyn(d) => vm::Expr::Load(d),
            }
        };
        match bit {
            Some(b) => TE {
                ty: Ty::T(Type::BOOL),
                e: vm::Expr::Un(Un::Bit(b), Box::new(e)),
            },
            None => TE { ty: Ty::T(ty), e },
        }
    }

    // ---------------------------------------------------------------- expressions

    fn string_literal(&mut self, s: &[u8], pos: Pos) -> R<TE> {
        let cap = s.len().max(1) as u16;
        let a = match self.string_lits.get(s) {
            Some(a) => *a,
            None => {
                let a = self.alloc(string_slots(cap), pos)?;
                crate::strings::write(&mut self.image, a as usize, cap, s);
                self.string_lits.insert(s.to_vec(), a);
                a
            }
        };
        Ok(TE {
            ty: Ty::T(Type::String(cap)),
            e: vm::Expr::AddrOf(Place::Abs(a)),
        })
    }

    fn string_temp(&mut self, pos: Pos) -> R<u32> {
        self.alloc(string_slots(MAX_STRING_LEN), pos)
    }

    fn expr(&mut self, e: &AExpr, sc: &mut Scope, expect: Option<&Type>) -> R<TE> {
        match e {
            AExpr::Lit(l, pos) => Ok(match l {
                Literal::Int(v) => TE {
                    ty: Ty::AnyInt(*v as i128),
                    e: vm::Expr::Const(0),
                },
                Literal::Real(v) => TE {
                    ty: Ty::AnyReal(*v),
                    e: vm::Expr::Const(0),
                },
                Literal::Time(ns) => {
                    let ns = i64::try_from(*ns)
                        .map_err(|_| self.e(*pos, ErrorKind::Invalid, "duration is too large"))?;
                    TE {
                        ty: Ty::T(Type::Elem(Elem::Time)),
                        e: vm::Expr::Const(ns as u64),
                    }
                }
                Literal::Bool(b) => TE {
                    ty: Ty::T(Type::BOOL),
                    e: vm::Expr::Const(*b as u64),
                },
                Literal::Str(s) => return self.string_literal(s, *pos),
            }),
            AExpr::Typed(tn, inner) => {
                let (t, _) = self.named_type(tn)?;
                let te = self.expr(inner, sc, Some(&t))?;
                let v = self.coerce(te, &t, inner.pos())?;
                Ok(TE { ty: Ty::T(t), e: v })
            }
            AExpr::EnumValue(tn, v) => {
                let (t, _) = self.named_type(tn)?;
                let Type::Enum(id) = t else {
                    return Err(self.e(
                        tn.pos,
                        ErrorKind::TypeMismatch,
                        format!("'{}' is not an enumeration", tn.text),
                    ));
                };
                let Some((_, val)) = self.enums[id as usize]
                    .values
                    .iter()
                    .find(|(n, _)| n == &v.text)
                else {
                    return Err(self.e(
                        v.pos,
                        ErrorKind::Undeclared,
                        format!("{} has no value '{}'", tn.text, v.text),
                    ));
                };
                Ok(TE {
                    ty: Ty::T(Type::Enum(id)),
                    e: vm::Expr::Const(*val as u64),
                })
            }
            AExpr::Var(a) => {
                if a.parts.is_empty() && self.lookup(&a.root, sc).is_none() {
                    if let Some(cands) = self.enum_values.get(&a.root.text) {
                        let pick = match expect {
                            Some(Type::Enum(id)) => cands.iter().find(|(e, _)| e == id).copied(),
                            _ => None,
                        }
                        .or(if cands.len() == 1 {
                            Some(cands[0])
                        } else {
                            None
                        });
                        return match pick {
                            Some((id, v)) => Ok(TE {
                                ty: Ty::T(Type::Enum(id)),
                                e: vm::Expr::Const(v as u64),
                            }),
                            None => Err(self.e(
                                a.root.pos,
                                ErrorKind::Invalid,
                                format!(
                                    "'{}' names values of several enumerations; write Type#{}",
                                    a.root.text, a.root.text
                                ),
                            )),
                        };
                    }
                }
                let lv = self.access(a, sc)?;
                if let Type::Fb(_) = lv.ty {
                    return Err(self.e(
                        a.root.pos,
                        ErrorKind::TypeMismatch,
                        "a function block instance is not a value; read one of its outputs",
                    ));
                }
                Ok(self.load(lv))
            }
            AExpr::Direct(d, pos) => {
                let name = d.to_string();
                let root = Name {
                    text: name,
                    pos: *pos,
                };
                let lv = self.access(
                    &Access {
                        root,
                        parts: Vec::new(),
                    },
                    sc,
                )?;
                Ok(self.load(lv))
            }
            AExpr::Unary(op, inner, pos) => {
                let te = self.expr(inner, sc, expect)?;
                self.unary(*op, te, *pos)
            }
            AExpr::Binary(op, l, r, pos) => {
                let lt = self.expr(l, sc, expect)?;
                let hint = match &lt.ty {
                    Ty::T(t) => Some(t.clone()),
                    _ => expect.cloned(),
                };
                let rt = self.expr(r, sc, hint.as_ref())?;
                self.binary(*op, lt, rt, *pos)
            }
            AExpr::Call(name, args, pos) => {
                let te = self.call_expr(name, args, sc, *pos, expect)?;
                if let (Ty::T(Type::Elem(Elem::Bool)), vm::Expr::Call(call)) = (&te.ty, &te.e) {
                    if self
                        .funcs
                        .get(call.func as usize)
                        .is_some_and(|f| f.ret.is_none())
                    {
                        return Err(self.e(
                            *pos,
                            ErrorKind::TypeMismatch,
                            format!("function '{}' returns no value", name.text),
                        ));
                    }
                }
                Ok(te)
            }
        }
    }

    /// Folds an expression whose operands are all constants.
    fn fold(&self, e: vm::Expr) -> vm::Expr {
        let e = self.fold_constants(e);
        match e {
            vm::Expr::Un(Un::NotBool, a) => match *a {
                vm::Expr::LoadAbs(s) => vm::Expr::NotAbs(s),
                other => vm::Expr::Un(Un::NotBool, Box::new(other)),
            },
            vm::Expr::Bin(op, ab) => match *ab {
                (vm::Expr::LoadAbs(x), vm::Expr::LoadAbs(y)) => vm::Expr::BinAbs(op, x, y),
                (a, vm::Expr::Const(k)) if !matches!(a, vm::Expr::Const(_)) => {
                    vm::Expr::BinK(op, Box::new(a), k)
                }
                pair => vm::Expr::Bin(op, Box::new(pair)),
            },
            other => other,
        }
    }

    fn fold_constants(&self, e: vm::Expr) -> vm::Expr {
        let all_const = match &e {
            vm::Expr::Un(_, a) | vm::Expr::Conv(_, a) => matches!(**a, vm::Expr::Const(_)),
            vm::Expr::Bin(_, ab) => {
                matches!(ab.0, vm::Expr::Const(_)) && matches!(ab.1, vm::Expr::Const(_))
            }
            _ => false,
        };
        if !all_const {
            return e;
        }
        let mut tmp = vm::Vm {
            mem: Vec::new(),
            frame: 0,
            now: 0,
            budget: 10,
            fault: None,
            fault_at: None,
            pou: 0,
        };
        let code = Code {
            functions: Vec::new(),
            fbs: Vec::new(),
        };
        let v = tmp.eval(&code, &e);
        if tmp.fault.is_some() {
            e
        } else {
            vm::Expr::Const(v)
        }
    }

    fn unary(&mut self, op: UnOp, te: TE, pos: Pos) -> R<TE> {
        match (op, &te.ty) {
            (UnOp::Plus, _) => Ok(te),
            (UnOp::Neg, Ty::AnyInt(v)) => Ok(TE {
                ty: Ty::AnyInt(-v),
                e: te.e,
            }),
            (UnOp::Neg, Ty::AnyReal(v)) => Ok(TE {
                ty: Ty::AnyReal(-v),
                e: te.e,
            }),
            (UnOp::Not, Ty::AnyInt(v)) => {
                // NOT of an untyped literal: take it as a DWORD-wide bit string.
                let e = self.fold(vm::Expr::Un(
                    Un::NotBits(IntKind::U32),
                    Box::new(vm::Expr::Const(*v as u64)),
                ));
                Ok(TE {
                    ty: Ty::T(Type::Elem(Elem::DWord)),
                    e,
                })
            }
            (_, Ty::T(t)) => {
                let Some(el) = t.elem() else {
                    return Err(self.e(
                        pos,
                        ErrorKind::TypeMismatch,
                        format!("operator does not apply to {}", self.type_name(t)),
                    ));
                };
                let un = match op {
                    UnOp::Neg if el.is_real() => Un::NegR(real_flag(el)),
                    UnOp::Neg if (el.is_int() && ik(el).signed()) || el == Elem::Time => {
                        Un::NegI(ik(el))
                    }
                    UnOp::Not if el == Elem::Bool => Un::NotBool,
                    UnOp::Not if el.is_bit() => Un::NotBits(ik(el)),
                    _ => {
                        let opn = if op == UnOp::Neg { "-" } else { "NOT" };
                        return Err(self.e(
                            pos,
                            ErrorKind::TypeMismatch,
                            format!("'{opn}' does not apply to {}", el.name()),
                        ));
                    }
                };
                let rt = match t {
                    Type::Subrange(e, _, _) => Type::Elem(*e),
                    t => t.clone(),
                };
                Ok(TE {
                    ty: Ty::T(rt),
                    e: self.fold(vm::Expr::Un(un, Box::new(te.e))),
                })
            }
            (UnOp::Not, Ty::AnyReal(_)) => {
                Err(self.e(pos, ErrorKind::TypeMismatch, "NOT does not apply to a real"))
            }
        }
    }

    fn literal_fold(&self, op: BinOp, a: &Ty, b: &Ty, pos: Pos) -> R<Option<TE>> {
        let cmp = |o: std::cmp::Ordering| -> bool {
            use std::cmp::Ordering::*;
            match op {
                BinOp::Eq => o == Equal,
                BinOp::Ne => o != Equal,
                BinOp::Lt => o == Less,
                BinOp::Le => o != Greater,
                BinOp::Gt => o == Greater,
                BinOp::Ge => o != Less,
                _ => false,
            }
        };
        let is_cmp = matches!(
            op,
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge
        );
        let boolean = |v: bool| TE {
            ty: Ty::T(Type::BOOL),
            e: vm::Expr::Const(v as u64),
        };
        match (a, b) {
            (Ty::AnyInt(x), Ty::AnyInt(y)) => {
                let (x, y) = (*x, *y);
                if is_cmp {
                    return Ok(Some(boolean(cmp(x.cmp(&y)))));
                }
                let v = match op {
                    BinOp::Add => x.checked_add(y),
                    BinOp::Sub => x.checked_sub(y),
                    BinOp::Mul => x.checked_mul(y),
                    BinOp::Div | BinOp::Mod if y == 0 => {
                        return Err(self.e(
                            pos,
                            ErrorKind::Invalid,
                            "division by zero in a constant expression",
                        ));
                    }
                    BinOp::Div => x.checked_div(y),
                    BinOp::Mod => x.checked_rem(y),
                    BinOp::And => Some(x & y),
                    BinOp::Or => Some(x | y),
                    BinOp::Xor => Some(x ^ y),
                    BinOp::Pow => {
                        return Ok(Some(TE {
                            ty: Ty::AnyReal((x as f64).powf(y as f64)),
                            e: vm::Expr::Const(0),
                        }));
                    }
                    _ => None,
                };
                match v.filter(|v| *v >= i64::MIN as i128 && *v <= u64::MAX as i128) {
                    Some(v) => Ok(Some(TE {
                        ty: Ty::AnyInt(v),
                        e: vm::Expr::Const(0),
                    })),
                    None => Err(self.e(pos, ErrorKind::Invalid, "constant expression overflows")),
                }
            }
            (Ty::AnyInt(_) | Ty::AnyReal(_), Ty::AnyInt(_) | Ty::AnyReal(_)) => {
                let f = |t: &Ty| match t {
                    Ty::AnyInt(v) => *v as f64,
                    Ty::AnyReal(v) => *v,
                    Ty::T(_) => 0.0,
                };
                let (x, y) = (f(a), f(b));
                if is_cmp {
                    return Ok(x.partial_cmp(&y).map(|o| boolean(cmp(o))));
                }
                let v = match op {
                    BinOp::Add => x + y,
                    BinOp::Sub => x - y,
                    BinOp::Mul => x * y,
                    BinOp::Div if y == 0.0 => {
                        return Err(self.e(
                            pos,
                            ErrorKind::Invalid,
                            "division by zero in a constant expression",
                        ));
                    }
                    BinOp::Div => x / y,
                    BinOp::Pow => x.powf(y),
                    _ => {
                        return Err(self.e(
                            pos,
                            ErrorKind::TypeMismatch,
                            "operator does not apply to reals",
                        ));
                    }
                };
                Ok(Some(TE {
                    ty: Ty::AnyReal(v),
                    e: vm::Expr::Const(0),
                }))
            }
            _ => Ok(None),
        }
    }

    /// The type two operands meet at, following the implicit widening rules.
    fn common(&self, a: &Ty, b: &Ty, pos: Pos) -> R<Type> {
        let base = |t: &Type| match t {
            Type::Subrange(e, _, _) => Type::Elem(*e),
            t => t.clone(),
        };
        match (a, b) {
            (Ty::T(x), Ty::AnyInt(_) | Ty::AnyReal(_)) => Ok(base(x)),
            (Ty::AnyInt(_) | Ty::AnyReal(_), Ty::T(y)) => Ok(base(y)),
            (Ty::T(x), Ty::T(y)) => {
                let (x, y) = (base(x), base(y));
                if x == y {
                    return Ok(x);
                }
                if let (Type::String(p), Type::String(q)) = (&x, &y) {
                    return Ok(Type::String((*p).max(*q)));
                }
                match (x.elem(), y.elem()) {
                    (Some(p), Some(q)) if widens(p, q) => Ok(y),
                    (Some(p), Some(q)) if widens(q, p) => Ok(x),
                    // Neither widens to the other (INT and UINT): the smallest type both
                    // widen to (DINT).
                    (Some(p), Some(q))
                        if Elem::ALL.iter().any(|t| widens(p, *t) && widens(q, *t)) =>
                    {
                        let t = Elem::ALL.iter().find(|t| widens(p, **t) && widens(q, **t));
                        Ok(Type::Elem(*t.unwrap_or(&Elem::LReal)))
                    }
                    _ => Err(self.e(
                        pos,
                        ErrorKind::TypeMismatch,
                        format!(
                            "type mismatch: {} and {}",
                            self.type_name(&x),
                            self.type_name(&y)
                        ),
                    )),
                }
            }
            _ => Err(self.e(pos, ErrorKind::TypeMismatch, "type mismatch")),
        }
    }

    fn binary(&mut self, op: BinOp, l: TE, r: TE, pos: Pos) -> R<TE> {
        if let Some(te) = self.literal_fold(op, &l.ty, &r.ty, pos)? {
            return Ok(te);
        }
        let time = Type::Elem(Elem::Time);
        // TIME * number and TIME / number.
        if matches!(op, BinOp::Mul | BinOp::Div)
            && matches!(&l.ty, Ty::T(t) if t.elem() == Some(Elem::Time))
        {
            let rt = match &r.ty {
                Ty::AnyInt(_) => Some(Type::Elem(Elem::LInt)),
                Ty::AnyReal(_) => Some(Type::Elem(Elem::LReal)),
                Ty::T(t) if t.elem().is_some_and(|e| e.is_num()) => Some(t.clone()),
                _ => None,
            };
            if let Some(rt) = rt {
                let re = rt.elem().unwrap_or(Elem::LInt);
                let rv = self.coerce(r, &rt, pos)?;
                let bin = match (op, re.is_real()) {
                    (BinOp::Mul, false) => Bin::MulTimeI,
                    (BinOp::Div, false) => Bin::DivTimeI,
                    (BinOp::Mul, true) => Bin::MulTimeR,
                    _ => Bin::DivTimeR,
                };
                return Ok(TE {
                    ty: Ty::T(time),
                    e: self.fold(vm::Expr::Bin(bin, Box::new((l.e, rv)))),
                });
            }
        }
        let ct = self.common(&l.ty, &r.ty, pos)?;
        let (lt_name, rt_name) = (self.ty_name(&l.ty), self.ty_name(&r.ty));
        let le = self.coerce(l, &ct, pos)?;
        let re = self.coerce(r, &ct, pos)?;
        let mismatch = |c: &Compiler| {
            let opname = format!("{op:?}").to_uppercase();
            c.e(
                pos,
                ErrorKind::TypeMismatch,
                format!("operator {opname} does not apply to {lt_name} and {rt_name}"),
            )
        };
        let is_cmp = matches!(
            op,
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge
        );
        if let Type::String(_) = ct {
            if !is_cmp {
                return Err(mismatch(self));
            }
            use std::cmp::Ordering::*;
            let (bin, swap_not) = match op {
                BinOp::Eq => (Bin::CmpS(Equal, false), false),
                BinOp::Ne => (Bin::CmpS(Equal, false), true),
                BinOp::Lt => (Bin::CmpS(Less, false), false),
                BinOp::Le => (Bin::CmpS(Less, true), false),
                BinOp::Gt => (Bin::CmpS(Greater, false), false),
                _ => (Bin::CmpS(Greater, true), false),
            };
            let e = vm::Expr::Bin(bin, Box::new((le, re)));
            let e = if swap_not {
                vm::Expr::Un(Un::NotBool, Box::new(e))
            } else {
                e
            };
            return Ok(TE {
                ty: Ty::T(Type::BOOL),
                e,
            });
        }
        let el = match &ct {
            Type::Enum(_) => {
                if !is_cmp {
                    return Err(mismatch(self));
                }
                Elem::DInt
            }
            t => t.elem().ok_or_else(|| mismatch(self))?,
        };
        let k = ik(el);
        let s = real_flag(el);
        let bin = if is_cmp {
            if el.is_real() {
                match op {
                    BinOp::Eq => Bin::EqR,
                    BinOp::Ne => Bin::NeR,
                    BinOp::Lt => Bin::LtR,
                    BinOp::Le => Bin::LeR,
                    BinOp::Gt => Bin::GtR,
                    _ => Bin::GeR,
                }
            } else {
                let sg = k.signed();
                match op {
                    BinOp::Eq => Bin::Eq,
                    BinOp::Ne => Bin::Ne,
                    BinOp::Lt => Bin::Lt(sg),
                    BinOp::Le => Bin::Le(sg),
                    BinOp::Gt => Bin::Gt(sg),
                    _ => Bin::Ge(sg),
                }
            }
        } else {
            match op {
                BinOp::And | BinOp::Or | BinOp::Xor if el == Elem::Bool || el.is_bit() => {
                    match op {
                        BinOp::And => Bin::And,
                        BinOp::Or => Bin::Or,
                        _ => Bin::Xor,
                    }
                }
                BinOp::Add if el.is_int() || el == Elem::Time => Bin::AddI(k),
                BinOp::Sub if el.is_int() || el == Elem::Time => Bin::SubI(k),
                BinOp::Mul if el.is_int() => Bin::MulI(k),
                BinOp::Div if el.is_int() => Bin::DivI(k),
                BinOp::Mod if el.is_int() => Bin::ModI(k),
                BinOp::Add if el.is_real() => Bin::AddR(s),
                BinOp::Sub if el.is_real() => Bin::SubR(s),
                BinOp::Mul if el.is_real() => Bin::MulR(s),
                BinOp::Div if el.is_real() => Bin::DivR(s),
                BinOp::Pow if el.is_real() => Bin::PowR(s),
                _ => return Err(mismatch(self)),
            }
        };
        let ty = if is_cmp { Type::BOOL } else { ct };
        Ok(TE {
            ty: Ty::T(ty),
            e: self.fold(vm::Expr::Bin(bin, Box::new((le, re)))),
        })
    }

    /// Converts an expression to type `to` if IEC allows it implicitly.
    fn coerce(&self, te: TE, to: &Type, pos: Pos) -> R<vm::Expr> {
        let mismatch = |c: &Compiler, from: &Ty| {
            c.e(
                pos,
                ErrorKind::TypeMismatch,
                format!(
                    "type mismatch: a {} value where {} is expected",
                    c.ty_name(from),
                    c.type_name(to)
                ),
            )
        };
        match &te.ty {
            Ty::AnyInt(v) => {
                let v = *v;
                let Some(el) = to.scalar() else {
                    return Err(mismatch(self, &te.ty));
                };
                if matches!(to, Type::Enum(_)) {
                    return Err(mismatch(self, &te.ty));
                }
                if el.is_real() {
                    let f = v as f64;
                    return Ok(vm::Expr::Const(if el == Elem::Real {
                        ((f as f32) as f64).to_bits()
                    } else {
                        f.to_bits()
                    }));
                }
                if el == Elem::Time {
                    return Err(mismatch(self, &te.ty));
                }
                let (lo, hi) = match to {
                    Type::Subrange(_, l, h) => (*l as i128, *h as i128),
                    _ => el.int_range().unwrap_or((0, 1)),
                };
                if v < lo || v > hi {
                    return Err(self.e(
                        pos,
                        ErrorKind::TypeMismatch,
                        format!("{v} does not fit {}", self.type_name(to)),
                    ));
                }
                Ok(vm::Expr::Const(v as i64 as u64))
            }
            Ty::AnyReal(f) => match to.elem() {
                Some(Elem::Real) => Ok(vm::Expr::Const(((*f as f32) as f64).to_bits())),
                Some(Elem::LReal) => Ok(vm::Expr::Const(f.to_bits())),
                _ => Err(mismatch(self, &te.ty)),
            },
            Ty::T(from) => {
                if from == to {
                    return Ok(te.e);
                }
                match (from, to) {
                    (Type::String(_), Type::String(_)) => return Ok(te.e),
                    (Type::Subrange(a, _, _), Type::Subrange(b, _, _)) if a == b => return Ok(te.e),
                    _ => {}
                }
                let (Some(f), Some(t)) = (from.elem(), to.elem()) else {
                    return Err(mismatch(self, &te.ty));
                };
                if !widens(f, t) {
                    return Err(mismatch(self, &te.ty));
                }
                Ok(self.fold(self.convert(te.e, f, t)))
            }
        }
    }

    /// Builds the conversion of a value from `f` to `t` (any pair of elementary types).
    fn convert(&self, e: vm::Expr, f: Elem, t: Elem) -> vm::Expr {
        let c = |cv: Conv, e: vm::Expr| vm::Expr::Conv(cv, Box::new(e));
        if f == t {
            return e;
        }
        match (f, t) {
            (_, Elem::Bool) if f.is_real() => c(Conv::RealToBool, e),
            (_, Elem::Bool) => c(Conv::IntToBool, e),
            (Elem::Time, t) if t.is_real() => c(Conv::NsToRealMs(real_flag(t)), e),
            (Elem::Time, t) => c(Conv::Int(ik(t)), c(Conv::NsToMs, e)),
            (f, Elem::Time) if f.is_real() => c(Conv::RealMsToNs, e),
            (_, Elem::Time) => c(Conv::MsToNs, e),
            (f, t) if f.is_real() && t.is_real() => {
                if t == Elem::Real {
                    c(Conv::ToF32, e)
                } else {
                    e
                }
            }
            (f, t) if f.is_real() => c(Conv::RealToInt(ik(t)), e),
            (f, t) if t.is_real() => c(
                Conv::IntToReal {
                    signed: ik(f).signed(),
                    f32: real_flag(t),
                },
                e,
            ),
            (_, t) => {
                // Integer to integer: a no-op when every value of f fits t's encoding.
                let (fl, fh) = ik(f).range();
                let (tl, th) = ik(t).range();
                if fl >= tl && fh <= th {
                    e
                } else {
                    c(Conv::Int(ik(t)), e)
                }
            }
        }
    }

    // ---------------------------------------------------------------- calls

    fn call_stmt(
        &mut self,
        target: &Access,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<StmtKind> {
        if target.parts.is_empty() && self.lookup(&target.root, sc).is_none() {
            let te = self.call_expr(&target.root, args, sc, pos, None)?;
            return Ok(StmtKind::Eval(te.e));
        }
        let lv = self.access(target, sc)?;
        let Type::Fb(id) = lv.ty else {
            return Err(self.e(
                target.root.pos,
                ErrorKind::TypeMismatch,
                format!("'{}' is not a function block instance", target.root.text),
            ));
        };
        let fb_name = self.fbs[id as usize].name.clone();
        let members = self.fbs[id as usize].members.clone();
        let (direct, ins, outs) = self.bind_args(&fb_name, &members, args, sc, pos, true)?;
        let kind = match self.fbs[id as usize].std {
            Some(s) => FbKind::Std(s),
            None => FbKind::User(self.fbs[id as usize].body),
        };
        let instance = self.place(lv);
        Ok(StmtKind::CallFb(Box::new(FbCall {
            instance,
            kind,
            direct,
            args: ins,
            outs,
        })))
    }

    /// Matches formal and informal arguments to parameters.
    #[allow(clippy::type_complexity)]
    fn bind_args(
        &mut self,
        pou: &str,
        params: &[Member],
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
        is_fb: bool,
    ) -> R<(bool, Box<[ArgIn]>, Box<[ArgOut]>)> {
        let positional: Vec<&Member> = params
            .iter()
            .filter(|m| matches!(m.kind, VarKind::Input | VarKind::InOut))
            .collect();
        let mut ins: Vec<ArgIn> = Vec::new();
        let mut outs: Vec<ArgOut> = Vec::new();
        let mut given: HashSet<String> = HashSet::new();
        let mut k = 0usize;
        let mut calls_user = false;
        for a in args {
            match a {
                Arg::Positional(e) => {
                    if !given.is_empty() && k == 0 {
                        return Err(self.e(
                            e.pos(),
                            ErrorKind::WrongArgument,
                            "positional arguments must come before named ones",
                        ));
                    }
                    let Some(m) = positional.get(k).copied() else {
                        return Err(self.e(
                            e.pos(),
                            ErrorKind::WrongArgument,
                            format!("{pou} takes {} positional arguments", positional.len()),
                        ));
                    };
                    k += 1;
                    given.insert(m.name.clone());
                    let arg = self.arg_in(pou, m, e, sc, &mut calls_user)?;
                    ins.push(arg);
                }
                Arg::Input(n, e) => {
                    let Some(m) = params.iter().find(|m| m.name == n.text) else {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("{pou} has no parameter '{}'", n.text),
                        ));
                    };
                    if !matches!(m.kind, VarKind::Input | VarKind::InOut) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("'{}' of {pou} is an output; use '=>'", n.text),
                        ));
                    }
                    if !given.insert(m.name.clone()) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("'{}' is given twice", n.text),
                        ));
                    }
                    let arg = self.arg_in(pou, &m.clone(), e, sc, &mut calls_user)?;
                    ins.push(arg);
                }
                Arg::Output(n, target, negate) => {
                    let Some(m) = params.iter().find(|m| m.name == n.text).cloned() else {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("{pou} has no parameter '{}'", n.text),
                        ));
                    };
                    if m.kind != VarKind::Output {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("'{}' of {pou} is not an output", n.text),
                        ));
                    }
                    let Some(t) = target else { continue };
                    let lv = self.access(t, sc)?;
                    self.check_writable(&lv, t.root.pos)?;
                    if *negate && !m.ty.is_bool() {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            "only BOOL outputs can be negated",
                        ));
                    }
                    let ok = lv.ty == m.ty
                        || matches!((&m.ty, &lv.ty), (Type::String(_), Type::String(_)))
                        || matches!((m.ty.elem(), lv.ty.elem()), (Some(a), Some(b)) if widens(a, b) && !matches!(lv.ty, Type::Subrange(..)));
                    if !ok || lv.bit.is_some() {
                        return Err(self.e(
                            t.root.pos,
                            ErrorKind::WrongArgument,
                            format!(
                                "output '{}' is {}, the target is {}",
                                n.text,
                                self.type_name(&m.ty),
                                self.type_name(&lv.ty)
                            ),
                        ));
                    }
                    if m.ty.elem() != lv.ty.elem()
                        && m.ty.scalar().is_some()
                        && m.ty.elem() != Some(Elem::Bool)
                    {
                        // Widening outputs: read through a conversion is not expressible as a
                        // copy, so only same-encoding widenings are accepted.
                        let (f, t) = (
                            m.ty.elem().unwrap_or(Elem::Bool),
                            lv.ty.elem().unwrap_or(Elem::Bool),
                        );
                        if f.is_real() != t.is_real() {
                            return Err(self.e(
                                t_root(target),
                                ErrorKind::WrongArgument,
                                format!(
                                    "output '{}' is {}; convert it explicitly",
                                    n.text,
                                    f.name()
                                ),
                            ));
                        }
                    }
                    let store = self.store_kind(&lv.ty);
                    outs.push(ArgOut {
                        param: m.offset,
                        target: self.place(lv),
                        store,
                        negate: *negate,
                    });
                }
            }
        }
        for m in params {
            if m.kind == VarKind::InOut && !given.contains(&m.name) {
                return Err(self.e(
                    pos,
                    ErrorKind::WrongArgument,
                    format!("VAR_IN_OUT '{}' of {pou} must be given", m.name),
                ));
            }
        }
        let _ = is_fb;
        Ok((!calls_user, ins.into_boxed_slice(), outs.into_boxed_slice()))
    }

    fn arg_in(
        &mut self,
        pou: &str,
        m: &Member,
        e: &AExpr,
        sc: &mut Scope,
        calls_user: &mut bool,
    ) -> R<ArgIn> {
        if contains_user_call(e, self) {
            *calls_user = true;
        }
        if m.kind == VarKind::InOut {
            let AExpr::Var(a) = e else {
                return Err(self.e(
                    e.pos(),
                    ErrorKind::WrongArgument,
                    format!("VAR_IN_OUT '{}' of {pou} needs a variable", m.name),
                ));
            };
            let lv = self.access(a, sc)?;
            self.check_writable(&lv, a.root.pos)?;
            if lv.ty != m.ty || lv.bit.is_some() {
                return Err(self.e(
                    e.pos(),
                    ErrorKind::WrongArgument,
                    format!(
                        "VAR_IN_OUT '{}' is {}, the variable is {}",
                        m.name,
                        self.type_name(&m.ty),
                        self.type_name(&lv.ty)
                    ),
                ));
            }
            let temp = self.alloc(1, e.pos())?;
            let p = self.place(lv);
            return Ok(ArgIn {
                value: vm::Expr::AddrOf(p),
                temp,
                param: m.offset,
                store: Store::Scalar,
            });
        }
        let te = self.expr(e, sc, Some(&m.ty))?;
        let value = self.coerce(te, &m.ty, e.pos()).map_err(|mut er| {
            er.kind = ErrorKind::WrongArgument;
            er.message = format!("argument '{}' of {pou}: {}", m.name, er.message);
            er
        })?;
        let store = self.store_kind(&m.ty);
        let temp = self.alloc(size_of(self, &m.ty), e.pos())?;
        Ok(ArgIn {
            value,
            temp,
            param: m.offset,
            store,
        })
    }

    fn call_expr(
        &mut self,
        name: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
        expect: Option<&Type>,
    ) -> R<TE> {
        if let Some(id) = self.func_id(name)? {
            let (fname, params, ret, result) = {
                let f = &self.funcs[id as usize];
                (f.name.clone(), f.params.clone(), f.ret.clone(), f.result)
            };
            let (direct, ins, outs) = self.bind_args(&fname, &params, args, sc, pos, false)?;
            sc.calls.push(id);
            let call = vm::Expr::Call(Box::new(FnCall {
                func: id,
                direct,
                args: ins,
                outs,
            }));
            let _ = result;
            return Ok(match ret {
                Some(t) => TE {
                    ty: Ty::T(t),
                    e: call,
                },
                None => TE {
                    ty: Ty::T(Type::BOOL),
                    e: call,
                },
            });
        }
        if self
            .fn_by_name
            .get(&name.text)
            .is_some_and(|l| matches!(l, Lookup::Busy))
        {
            return Err(self.e(
                pos,
                ErrorKind::Invalid,
                format!(
                    "function '{}' calls itself (recursion is not allowed)",
                    name.text
                ),
            ));
        }
        crate::builtins::call(self, name, args, sc, pos, expect)
    }

    // Hooks for the builtins module.
    pub(crate) fn b_args(
        &mut self,
        args: &[Arg],
        sc: &mut Scope,
        fname: &str,
    ) -> R<Vec<(TE, Pos)>> {
        let mut out = Vec::new();
        for a in args {
            match a {
                Arg::Positional(e) | Arg::Input(_, e) => {
                    out.push((self.expr(e, sc, None)?, e.pos()))
                }
                Arg::Output(n, _, _) => {
                    return Err(self.e(
                        n.pos,
                        ErrorKind::WrongArgument,
                        format!("{fname} has no outputs"),
                    ));
                }
            }
        }
        Ok(out)
    }
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
        AExpr::Call(n, args, _) => {
            c.fn_asts.contains_key(&n.text)
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
type FieldInit<'i> = (u32, Type, Option<Vec<u64>>, Option<&'i Init>);

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
        let a = self.alloc(1, pos)?;
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
    pub(crate) fn new_string_temp(&mut self, pos: Pos) -> R<u32> {
        self.string_temp(pos)
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
    vm::Expr::Builtin(b, args.into_boxed_slice(), dest)
}

pub(crate) fn literal_elem(t: &Ty) -> Option<Elem> {
    elem_of(t)
}
