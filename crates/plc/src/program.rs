//! The compiled program: code, initial memory image, symbols, located variables and tasks.

use std::sync::Arc;
use std::time::Duration;

use crate::ast::VarKind;
use crate::lexer::{Area, DirectAddr};
use crate::types::{Elem, EnumType, StructType, Type};
use crate::vm::{Block, Code};

/// A variable or member as the symbol table knows it.
#[derive(Debug, Clone)]
pub(crate) struct Symbol {
    pub name: String,
    pub ty: Type,
    pub addr: u32,
    pub kind: VarKind,
    pub retain: bool,
    /// A VAR_IN_OUT: the slot holds the address of the actual variable.
    pub indirect: bool,
}

/// Layout of a function block type (user or standard).
#[derive(Debug, Clone)]
pub(crate) struct FbLayout {
    pub name: String,
    /// Members; `addr` is the offset in the instance.
    pub members: Vec<Symbol>,
}

/// A variable at a direct address, copied to or from an image every scan.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Located {
    pub at: DirectAddr,
    pub slot: u32,
    pub elem: Elem,
}

/// A program instance and its code.
#[derive(Debug)]
pub(crate) struct ProgramInstance {
    pub name: String,
    pub pou_type: String,
    pub pou: u32,
    pub vars: Vec<Symbol>,
    pub body: Block,
}

/// An elementary variable of a program, as [`Program::variables`] lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VariableInfo {
    /// Path for [`crate::Runtime::resolve`] (upper case).
    pub path: String,
    /// IEC type name.
    pub type_name: String,
    /// Declared RETAIN (or inside a RETAIN instance).
    pub retain: bool,
    /// Direct address of a located variable.
    pub location: Option<DirectAddr>,
}

/// An elementary leaf of the variable tree.
#[derive(Debug, Clone)]
pub(crate) struct Leaf {
    pub path: String,
    pub slot: u32,
    pub ty: Type,
    pub retain: bool,
}

/// A task of the CONFIGURATION, for the kernel to put on the executive.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskDesc {
    /// Task name (upper case); `DEFAULT` for the implicit task of programs without one.
    pub name: String,
    /// Period, or `None` for a task that runs on every call of
    /// [`crate::Runtime::scan`] (the standard's cyclic task without INTERVAL).
    pub interval: Option<Duration>,
    /// IEC priority: 0 is the most urgent.
    pub priority: u32,
    /// For an event task (`SINGLE := var`): the BOOL global whose rising edge activates
    /// it. [`crate::Runtime::scan`] runs it on the scan that sees the edge.
    pub trigger: Option<String>,
    pub(crate) trigger_slot: Option<u32>,
    /// Program instance names run by this task, in order.
    pub programs: Vec<String>,
    pub(crate) program_ids: Vec<usize>,
}

/// A compiled Structured Text program, ready to be instantiated by
/// [`crate::Runtime::new`]. Immutable and shareable between runtime instances.
#[derive(Debug)]
pub struct Program {
    pub(crate) file: String,
    pub(crate) code: Code,
    pub(crate) init: Vec<u8>,
    pub(crate) globals: Vec<Symbol>,
    pub(crate) instances: Vec<ProgramInstance>,
    pub(crate) tasks: Vec<TaskDesc>,
    pub(crate) pou_names: Vec<Arc<str>>,
    pub(crate) enums: Vec<EnumType>,
    pub(crate) structs: Vec<StructType>,
    pub(crate) fbs: Vec<FbLayout>,
    pub(crate) located: Vec<Located>,
    pub(crate) warnings: Vec<crate::error::Warning>,
    pub(crate) lines: crate::compiler::LineMap,
    pub(crate) image_sizes: [usize; 3],
    pub(crate) pou_count: usize,
}

impl Program {
    /// The file name the program was compiled from.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn file(&self) -> &str {
        &self.file
    }
    /// What the compiler accepted with a warning (an assignment to a VAR_INPUT inside
    /// its own POU, ...).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn warnings(&self) -> &[crate::error::Warning] {
        &self.warnings
    }
    /// Tasks declared by the CONFIGURATION (or the implicit `DEFAULT` task).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn tasks(&self) -> &[TaskDesc] {
        &self.tasks
    }
    /// Names of the program instances, in task order.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn program_instances(&self) -> impl Iterator<Item = &str> {
        self.instances.iter().map(|i| i.name.as_str())
    }
    /// Number of POUs (programs, function blocks, functions) in the source.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pou_count(&self) -> usize {
        self.pou_count
    }
    /// Bytes of PLC memory a runtime instance allocates.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn memory_bytes(&self) -> usize {
        self.init.len()
    }
    /// Bytes of the input (`%I`), output (`%Q`) and marker (`%M`) images the located
    /// variables need.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn image_size(&self, area: Area) -> usize {
        self.image_sizes[area_index(area)]
    }
    /// Members of a structure or function block type, offsets relative to its start.
    pub(crate) fn member_symbols(&self, ty: &Type) -> Option<Vec<Symbol>> {
        match ty {
            Type::Struct(id) => self.structs.get(*id as usize).map(|s| {
                s.fields
                    .iter()
                    .map(|f| Symbol {
                        name: f.name.clone(),
                        ty: f.ty.clone(),
                        addr: f.offset,
                        kind: VarKind::Local,
                        retain: false,
                        indirect: false,
                    })
                    .collect()
            }),
            Type::Fb(id) => self.fbs.get(*id as usize).map(|f| f.members.clone()),
            _ => None,
        }
    }

    /// Every elementary leaf of every global and program variable (arrays expanded,
    /// structures and function block instances by member), with its retain flag.
    pub(crate) fn leaves(&self) -> Vec<Leaf> {
        let mut out = Vec::new();
        for g in &self.globals {
            self.walk(g.name.clone(), &g.ty, g.addr, g.retain, &mut out);
        }
        for i in &self.instances {
            for v in &i.vars {
                self.walk(
                    format!("{}.{}", i.name, v.name),
                    &v.ty,
                    v.addr,
                    v.retain,
                    &mut out,
                );
            }
        }
        out
    }

    fn walk(&self, path: String, ty: &Type, slot: u32, retain: bool, out: &mut Vec<Leaf>) {
        match ty {
            Type::Array(a) => {
                let mut idx: Vec<i64> = a.dims.iter().map(|(l, _)| *l).collect();
                for k in 0..a.len() {
                    let label: Vec<String> = idx.iter().map(|i| i.to_string()).collect();
                    let at = slot + k as u32 * a.elem_size;
                    self.walk(
                        format!("{path}[{}]", label.join(",")),
                        &a.elem,
                        at,
                        retain,
                        out,
                    );
                    for d in (0..idx.len()).rev() {
                        idx[d] += 1;
                        if idx[d] <= a.dims[d].1 {
                            break;
                        }
                        idx[d] = a.dims[d].0;
                    }
                }
            }
            Type::Struct(_) | Type::Fb(_) => {
                for m in self.member_symbols(ty).unwrap_or_default() {
                    if m.indirect || m.kind == VarKind::Temp {
                        continue;
                    }
                    let at = slot + m.addr;
                    self.walk(
                        format!("{path}.{}", m.name),
                        &m.ty,
                        at,
                        retain || m.retain,
                        out,
                    );
                }
            }
            t => out.push(Leaf {
                path,
                slot,
                ty: t.clone(),
                retain,
            }),
        }
    }

    /// Every elementary variable a runtime can monitor or force, by path (globals,
    /// `INSTANCE.VAR`, members and array elements), with its type, retain flag and
    /// direct address. For browsing in an HMI; build it once, not per scan.
    ///
    /// Real-time: no (allocates).
    pub fn variables(&self) -> Vec<VariableInfo> {
        self.leaves()
            .into_iter()
            .map(|l| VariableInfo {
                type_name: self.type_name(&l.ty),
                location: self.located.iter().find(|x| x.slot == l.slot).map(|x| x.at),
                retain: l.retain,
                path: l.path,
            })
            .collect()
    }

    pub(crate) fn type_name(&self, ty: &Type) -> String {
        match ty {
            Type::Elem(e) => e.name().to_string(),
            Type::String(n) => format!("STRING[{n}]"),
            Type::WString(n) => format!("WSTRING[{n}]"),
            Type::Enum(id) => self
                .enums
                .get(*id as usize)
                .map_or("ENUM".into(), |e| e.name.clone()),
            Type::Subrange(e, lo, hi) => format!("{}({lo}..{hi})", e.name()),
            Type::Array(a) => {
                let dims: Vec<String> = a.dims.iter().map(|(l, h)| format!("{l}..{h}")).collect();
                format!("ARRAY[{}] OF {}", dims.join(","), self.type_name(&a.elem))
            }
            Type::Struct(id) => self
                .structs
                .get(*id as usize)
                .map_or("STRUCT".into(), |s| s.name.clone()),
            Type::Fb(id) => self
                .fbs
                .get(*id as usize)
                .map_or("FB".into(), |f| f.name.clone()),
            Type::Pointer(t) => format!("POINTER TO {}", self.type_name(t)),
            Type::Reference(t) => format!("REFERENCE TO {}", self.type_name(t)),
            Type::Interface(_) => "INTERFACE".into(),
        }
    }
}

pub(crate) fn area_index(a: Area) -> usize {
    match a {
        Area::Input => 0,
        Area::Output => 1,
        Area::Memory => 2,
    }
}
