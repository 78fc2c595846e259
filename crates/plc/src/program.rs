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
    pub(crate) init: Vec<u64>,
    pub(crate) globals: Vec<Symbol>,
    pub(crate) instances: Vec<ProgramInstance>,
    pub(crate) tasks: Vec<TaskDesc>,
    pub(crate) pou_names: Vec<Arc<str>>,
    pub(crate) enums: Vec<EnumType>,
    pub(crate) structs: Vec<StructType>,
    pub(crate) fbs: Vec<FbLayout>,
    pub(crate) located: Vec<Located>,
    pub(crate) image_sizes: [usize; 3],
    pub(crate) pou_count: usize,
}

impl Program {
    /// The file name the program was compiled from.
    pub fn file(&self) -> &str {
        &self.file
    }
    /// Tasks declared by the CONFIGURATION (or the implicit `DEFAULT` task).
    pub fn tasks(&self) -> &[TaskDesc] {
        &self.tasks
    }
    /// Names of the program instances, in task order.
    pub fn program_instances(&self) -> impl Iterator<Item = &str> {
        self.instances.iter().map(|i| i.name.as_str())
    }
    /// Number of POUs (programs, function blocks, functions) in the source.
    pub fn pou_count(&self) -> usize {
        self.pou_count
    }
    /// Slots of PLC memory a runtime instance allocates (8 bytes each).
    pub fn memory_slots(&self) -> usize {
        self.init.len()
    }
    /// Bytes of the input (`%I`), output (`%Q`) and marker (`%M`) images the located
    /// variables need.
    pub fn image_size(&self, area: Area) -> usize {
        self.image_sizes[area_index(area)]
    }
    pub(crate) fn type_name(&self, ty: &Type) -> String {
        match ty {
            Type::Elem(e) => e.name().to_string(),
            Type::String(n) => format!("STRING[{n}]"),
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
