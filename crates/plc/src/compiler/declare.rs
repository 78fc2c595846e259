//! Declarations: named types and their layout, initial values, function block and function signatures, globals, program instances and POU bodies.

use super::*;

impl<'a> Compiler<'a> {
    // ---------------------------------------------------------------- types

    pub(super) fn named_type(&mut self, n: &Name) -> R<(Type, Option<Vec<u8>>)> {
        if let Some(t) = self.named.get(&n.text) {
            return Ok(t.clone());
        }
        if let Some(e) = Elem::from_name(&n.text) {
            return Ok((Type::Elem(e), None));
        }
        if n.text == "STRING" {
            return Ok((Type::String(DEFAULT_STRING_LEN), None));
        }
        if n.text == "WSTRING" {
            return Ok((Type::WString(DEFAULT_STRING_LEN), None));
        }
        // The PLCopen axis reference holds the number of a configured axis.
        if matches!(n.text.as_str(), "AXIS_REF" | "AXIS_REF_SM3") {
            return Ok((Type::Elem(Elem::UDInt), None));
        }
        if let Some(id) = self.fb_id(n)? {
            return Ok((Type::Fb(id), None));
        }
        if self.iface_asts.contains_key(&n.text) {
            return Ok((Type::Interface(self.iface(n)?), None));
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
            fb: None,
            for_vars: Vec::new(),
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

    pub(super) fn type_spec(
        &mut self,
        spec: &TypeSpec,
        name: Option<&str>,
        scope: &Scope,
    ) -> R<(Type, Option<Vec<u8>>)> {
        match spec {
            TypeSpec::Named(n) => self.named_type(n),
            TypeSpec::Pointer(t) => {
                let (t, _) = self.type_spec(t, None, scope)?;
                Ok((Type::Pointer(Arc::new(t)), None))
            }
            TypeSpec::Reference(t, pos) => {
                let (t, _) = self.type_spec(t, None, scope)?;
                if matches!(t, Type::Reference(_)) {
                    return Err(self.e(
                        *pos,
                        ErrorKind::Invalid,
                        "a REFERENCE TO a REFERENCE is not allowed; use one REFERENCE",
                    ));
                }
                Ok((Type::Reference(Arc::new(t)), None))
            }
            TypeSpec::String { len, wide, pos } => {
                self.string_type(len.as_ref(), *wide, *pos, scope)
            }
            TypeSpec::Array { dims, elem, pos } => self.array_type(dims, elem, *pos, scope),
            TypeSpec::Struct { fields, union, pos } => {
                self.struct_type(fields, *union, *pos, name, scope)
            }
            TypeSpec::Enum { values, base, pos } => {
                self.enum_type(values, base.as_ref(), *pos, name, scope)
            }
            TypeSpec::Subrange { base, low, high } => self.subrange_type(base, low, high, scope),
        }
    }

    /// STRING and WSTRING, of `len` characters or the default length.
    fn string_type(
        &mut self,
        len: Option<&AExpr>,
        wide: bool,
        pos: Pos,
        scope: &Scope,
    ) -> R<(Type, Option<Vec<u8>>)> {
        let n = match len {
            Some(e) => self.const_int_in(e, scope)?,
            None => DEFAULT_STRING_LEN as i128,
        };
        if n < 1 || n > MAX_STRING_LEN as i128 {
            return Err(self.e(
                pos,
                ErrorKind::Invalid,
                format!(
                    "{} length must be 1..{MAX_STRING_LEN}",
                    if wide { "WSTRING" } else { "STRING" }
                ),
            ));
        }
        if wide {
            Ok((Type::WString(n as u16), None))
        } else {
            Ok((Type::String(n as u16), None))
        }
    }

    /// An ARRAY: its bounds, its element type and the template repeated.
    fn array_type(
        &mut self,
        dims: &[(AExpr, AExpr)],
        elem: &TypeSpec,
        pos: Pos,
        scope: &Scope,
    ) -> R<(Type, Option<Vec<u8>>)> {
        let mut bounds = Vec::new();
        for (lo, hi) in dims {
            let l = self.const_int_in(lo, scope)?;
            let h = self.const_int_in(hi, scope)?;
            if h < l
                || h - l >= MAX_BYTES as i128
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
        if count.saturating_mul(elem_size as u64) > MAX_BYTES {
            return Err(self.e(pos, ErrorKind::Invalid, "array is too large"));
        }
        let at = Type::Array(Arc::new(ArrayType {
            dims: bounds,
            elem: et,
            elem_size,
        }));
        let tpl = etpl.map(|t| t.repeat(count as usize));
        Ok((at, tpl))
    }

    /// A STRUCT or a UNION (`union`), registered as `name`; its template is kept with it.
    fn struct_type(
        &mut self,
        fields: &[ast::VarDecl],
        union: bool,
        pos: Pos,
        name: Option<&str>,
        scope: &Scope,
    ) -> R<(Type, Option<Vec<u8>>)> {
        let mut fs: Vec<Field> = Vec::new();
        let mut off = 0u32;
        let mut align = 1u32;
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
                let a = align_of(self, &t);
                align = align.max(a);
                // A union's members all start at 0 and share its bytes.
                let at = if union { 0 } else { align_up(off, a) };
                fs.push(Field {
                    name: n.text.clone(),
                    ty: t.clone(),
                    offset: at,
                });
                inits.push((at, t.clone(), tpl.clone(), d.init.as_ref()));
                off = off.max(at.saturating_add(size_of(self, &t)));
            }
        }
        // Padded to its alignment, so the elements of an array of it stay aligned.
        let off = align_up(off, align);
        if off as u64 > MAX_BYTES {
            return Err(self.e(pos, ErrorKind::Invalid, "structure is too large"));
        }
        let mut tpl = vec![0u8; off as usize];
        for (k, (o, t, ttpl, init)) in inits.into_iter().enumerate() {
            // A union starts as its first member's initial value, then takes
            // every member's explicit one in order.
            if !union || k == 0 {
                let sub = ttpl.unwrap_or_else(|| self.template(&t));
                tpl[o as usize..o as usize + sub.len()].copy_from_slice(&sub);
            }
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
                align,
            },
            tpl,
        ));
        Ok((Type::Struct(id), None))
    }

    /// An enumeration, registered as `name`; each value's name is looked up by later uses.
    fn enum_type(
        &mut self,
        values: &[(Name, Option<AExpr>)],
        base: Option<&Name>,
        pos: Pos,
        name: Option<&str>,
        scope: &Scope,
    ) -> R<(Type, Option<Vec<u8>>)> {
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
            return Err(self.e(pos, ErrorKind::Invalid, "empty enumeration"));
        }
        let ename = name.map_or_else(|| format!("ENUM#{id}"), str::to_string);
        self.enums.push(EnumType {
            name: ename,
            values: vals,
        });
        Ok((Type::Enum(id), None))
    }

    fn subrange_type(
        &mut self,
        base: &Name,
        low: &AExpr,
        high: &AExpr,
        scope: &Scope,
    ) -> R<(Type, Option<Vec<u8>>)> {
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

    /// Default initial bytes of a type.
    pub(super) fn template(&self, t: &Type) -> Vec<u8> {
        let scalar = |v: u64| {
            let mut b = vec![0u8; size_of(self, t) as usize];
            repr_of(t).store(&mut b, 0, v);
            b
        };
        match t {
            Type::Elem(_) | Type::Pointer(_) | Type::Reference(_) | Type::Interface(_) => {
                vec![0; size_of(self, t) as usize]
            }
            Type::String(_) | Type::WString(_) => vec![0; size_of(self, t) as usize],
            Type::Enum(id) => scalar(self.enums[*id as usize].values[0].1 as u64),
            // IEC: a subrange starts at its lower limit unless initialised.
            Type::Subrange(_, l, _) => scalar(*l as u64),
            Type::Array(a) => {
                let e = self.template(&a.elem);
                e.repeat(a.len() as usize)
            }
            Type::Struct(id) => self.structs[*id as usize].1.clone(),
            Type::Fb(id) => self.fbs[*id as usize].template.clone(),
        }
    }

    /// Writes an initializer into `tpl` at `at`.
    /// Puts a POU's scalar named constants in `scope` before its declarations are laid
    /// out, so that, as in CODESYS, an array declared above `VAR CONSTANT n : INT := 16;
    /// END_VAR` may have `n` as a bound. A constant whose value needs something not known
    /// yet is left to its declaration, which puts every constant in again with its place.
    fn constants_ahead(&mut self, blocks: &[ast::VarBlock], scope: &mut Scope) {
        for b in blocks {
            if !b.constant || b.kind == VarKind::External {
                continue;
            }
            for d in &b.decls {
                let Ok((t, tpl)) = self.type_spec(&d.ty, None, scope) else {
                    continue;
                };
                if t.scalar().is_none() {
                    continue;
                }
                let mut value = tpl.unwrap_or_else(|| self.template(&t));
                if let Some(i) = &d.init
                    && self.apply_init(&t, i, &mut value, 0, scope).is_err()
                {
                    continue;
                }
                for n in &d.names {
                    scope.vars.entry(n.text.clone()).or_insert(VarInfo {
                        ty: t.clone(),
                        loc: Loc::Abs(0),
                        kind: b.kind,
                        constant: true,
                        const_val: Some(repr_of(&t).load(&value, 0)),
                        input_area: false,
                    });
                }
            }
        }
    }

    pub(super) fn apply_init(
        &mut self,
        t: &Type,
        init: &Init,
        tpl: &mut [u8],
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
                        repr_of(t).store(tpl, at, v);
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
                let mut tmp = vec![0u8; string_bytes(*cap) as usize];
                crate::strings::write(&mut tmp, 0, *cap, s);
                tpl[at..at + tmp.len()].copy_from_slice(&tmp);
                Ok(())
            }
            (Init::Expr(AExpr::Lit(Literal::WStr(s), _)), Type::WString(cap)) => {
                let mut tmp = vec![0u8; crate::types::wstring_bytes(*cap) as usize];
                crate::strings::write_units(&mut tmp, 0, *cap, true, s);
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

    pub(super) fn fb_id(&mut self, n: &Name) -> R<Option<u32>> {
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
                    offset: 8 * i as u32,
                    kind: if *d == Dir::In {
                        VarKind::Input
                    } else {
                        VarKind::Output
                    },
                    constant: false,
                    retain: false,
                })
                .collect();
            let mut template = vec![0u8; 8 * s.size() as usize];
            s.init_hidden(&mut template);
            let id = self.fbs.len() as u32;
            self.fbs.push(FbInfo {
                name: s.name().into(),
                members,
                size: 8 * s.size(),
                template,
                std: Some(s),
                body: 0,
                methods: Vec::new(),
                base: None,
                interfaces: Vec::new(),
                properties: Vec::new(),
                own_start: 0,
            });
            self.fb_by_name.insert(n.text.clone(), Lookup::Found(id));
            return Ok(Some(id));
        }
        if self.fb_asts.contains_key(&n.text) {
            return self.fb_type(n).map(Some);
        }
        Ok(None)
    }

    pub(super) fn fb_type(&mut self, n: &Name) -> R<u32> {
        if let Some(Lookup::Found(id)) = self.fb_by_name.get(&n.text) {
            return Ok(*id);
        }
        let pou = self.fb_asts[&n.text];
        self.fb_by_name.insert(n.text.clone(), Lookup::Busy);
        let r = self.fb_layout(pou);
        match r {
            Ok(mut info) => {
                let id = self.fbs.len() as u32;
                Repr::U64.store(&mut info.template, TAG_OFFSET as usize, id as u64 + 1);
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

    /// The block a FUNCTION_BLOCK EXTENDS: one of the program's.
    fn extended_fb(&mut self, bn: &Name) -> R<u32> {
        match self.fb_id(bn)? {
            Some(id) if self.fbs[id as usize].std.is_none() => Ok(id),
            Some(_) => Err(self.e(
                bn.pos,
                ErrorKind::Invalid,
                format!(
                    "'{}' is a standard function block; EXTENDS needs a FUNCTION_BLOCK of this program",
                    bn.text
                ),
            )),
            None => Err(self.e(
                bn.pos,
                ErrorKind::Undeclared,
                format!("no FUNCTION_BLOCK named '{}' to extend", bn.text),
            )),
        }
    }

    /// The interfaces a FUNCTION_BLOCK IMPLEMENTS.
    fn implemented_interfaces(&mut self, pou: &'a ast::Pou) -> R<Vec<u32>> {
        let mut interfaces = Vec::new();
        for i in &pou.implements {
            if !self.iface_asts.contains_key(&i.text) {
                return Err(self.e(
                    i.pos,
                    ErrorKind::Undeclared,
                    format!("no INTERFACE named '{}'", i.text),
                ));
            }
            interfaces.push(self.iface(i)?);
        }
        Ok(interfaces)
    }

    pub(super) fn fb_layout(&mut self, pou: &'a ast::Pou) -> R<FbInfo> {
        let mut members: Vec<Member> = Vec::new();
        // The type tag: 8 bytes at the start, where CODESYS keeps the block's table of
        // methods.
        let mut off = 8u32;
        let mut template: Vec<u8> = vec![0; 8];
        let mut base = None;
        let mut methods = Vec::new();
        let mut properties = Vec::new();
        if let Some(bn) = &pou.extends {
            let id = self.extended_fb(bn)?;
            let b = &self.fbs[id as usize];
            members = b.members.clone();
            template = b.template.clone();
            off = b.size;
            methods = b.methods.clone();
            properties = b.properties.clone();
            base = Some(id);
        }
        let own_start = off;
        let interfaces = self.implemented_interfaces(pou)?;
        let mut scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::FunctionBlock,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
            fb: None,
            for_vars: Vec::new(),
        };
        self.constants_ahead(&pou.vars, &mut scope);
        for (prefix, b) in fb_member_blocks(pou) {
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
                    let name = format!("{prefix}{}", n.text);
                    if let Some(m) = members.iter().find(|m| m.name == name) {
                        let inherited = m.offset < own_start;
                        return Err(self.e(
                            n.pos,
                            ErrorKind::Duplicate,
                            if inherited {
                                format!("'{}' is already declared in the base block", n.text)
                            } else {
                                format!("'{}' is already declared", n.text)
                            },
                        ));
                    }
                    let (size, align) = if b.kind == VarKind::InOut {
                        (8, 8)
                    } else {
                        (size_of(self, &t), align_of(self, &t))
                    };
                    off = align_up(off, align);
                    template.resize(off as usize, 0);
                    let mut sub = if b.kind == VarKind::InOut {
                        vec![0; 8]
                    } else {
                        tpl.clone().unwrap_or_else(|| self.template(&t))
                    };
                    if let (Some(i), false) = (&d.init, b.kind == VarKind::InOut) {
                        self.apply_init(&t, i, &mut sub, 0, &scope)?;
                    }
                    template.extend_from_slice(&sub);
                    // Named constants serve as bounds of the declarations that follow.
                    if b.constant && prefix.is_empty() && t.scalar().is_some() {
                        scope.vars.insert(
                            n.text.clone(),
                            VarInfo {
                                ty: t.clone(),
                                loc: Loc::Rel(off),
                                kind: b.kind,
                                constant: true,
                                const_val: Some(repr_of(&t).load(&sub, 0)),
                                input_area: false,
                            },
                        );
                    }
                    members.push(Member {
                        name,
                        ty: t.clone(),
                        offset: off,
                        kind: if b.kind == VarKind::Inst {
                            VarKind::Local
                        } else {
                            b.kind
                        },
                        constant: b.constant,
                        retain: b.retain,
                    });
                    off = off.saturating_add(size);
                }
            }
        }
        let off = align_up(off, 8);
        template.resize(off as usize, 0);
        if off as u64 > MAX_BYTES {
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
            methods,
            base,
            interfaces,
            properties,
            own_start,
        })
    }

    pub(super) fn func_id(&mut self, n: &Name) -> R<Option<u32>> {
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

    pub(super) fn func(&mut self, n: &Name) -> R<u32> {
        if let Some(Lookup::Found(id)) = self.fn_by_name.get(&n.text) {
            return Ok(*id);
        }
        let pou = self.fn_asts[&n.text];
        self.fn_by_name.insert(n.text.clone(), Lookup::Busy);
        let id = self.callable(&pou.name, &pou.ret, &pou.vars, &pou.name.text)?;
        self.fn_by_name.insert(n.text.clone(), Lookup::Found(id));
        Ok(id)
    }

    /// A function's or method's result type: none for VOID or without one; never a
    /// function block.
    fn return_type(
        &mut self,
        name: &Name,
        ret_spec: &Option<TypeSpec>,
        scope: &Scope,
    ) -> R<Option<Type>> {
        let ret = match ret_spec {
            Some(TypeSpec::Named(t)) if t.text == "VOID" => None,
            Some(spec) => Some(self.type_spec(spec, None, scope)?.0),
            None => None,
        };
        if let Some(Type::Fb(_)) = ret {
            return Err(self.e(
                name.pos,
                ErrorKind::Invalid,
                "a function cannot return a function block",
            ));
        }
        Ok(ret)
    }

    /// A variable's slot in a static frame, its initial value written there unless it is a
    /// VAR_IN_OUT (`inout`: the slot holds an address).
    fn frame_slot(
        &mut self,
        t: &Type,
        tpl: &Option<Vec<u8>>,
        init: Option<&Init>,
        inout: bool,
        pos: Pos,
        scope: &Scope,
    ) -> R<u32> {
        let size = if inout { 8 } else { size_of(self, t) };
        let a = self.alloc(size, pos)?;
        if !inout {
            let mut sub = tpl.clone().unwrap_or_else(|| self.template(t));
            if let Some(i) = init {
                self.apply_init(t, i, &mut sub, 0, scope)?;
            }
            self.image[a as usize..a as usize + sub.len()].copy_from_slice(&sub);
        }
        Ok(a)
    }

    /// Lays out a function or method: a static frame with the result, parameters and
    /// locals (functions and methods cannot recurse, so one frame each is enough).
    pub(super) fn callable(
        &mut self,
        name: &Name,
        ret_spec: &Option<TypeSpec>,
        vars: &[ast::VarBlock],
        shown: &str,
    ) -> R<u32> {
        let mut scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::Function,
            pou: 0,
            loops: 0,
            calls: Vec::new(),
            fb: None,
            for_vars: Vec::new(),
        };
        let ret = self.return_type(name, ret_spec, &scope)?;
        let start = self.image.len() as u32;
        let result = self.alloc(ret.as_ref().map_or(8, |t| size_of(self, t)), name.pos)?;
        if let Some(t) = &ret {
            let tpl = self.template(t);
            self.image[result as usize..result as usize + tpl.len()].copy_from_slice(&tpl);
        }
        let mut locals: HashMap<String, VarInfo> = HashMap::new();
        let mut params: Vec<Member> = Vec::new();
        if let Some(t) = &ret {
            locals.insert(
                name.text.clone(),
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
        self.constants_ahead(vars, &mut scope);
        for b in vars {
            if matches!(b.kind, VarKind::Global) {
                return Err(self.e(
                    name.pos,
                    ErrorKind::Invalid,
                    "VAR_GLOBAL is not allowed inside a function",
                ));
            }
            if b.kind == VarKind::Inst {
                continue; // laid out in the instance by fb_layout
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
                    let a = self.frame_slot(&t, &tpl, d.init.as_ref(), inout, n.pos, &scope)?;
                    let const_val = if b.constant && t.scalar().is_some() {
                        Some(repr_of(&t).load(&self.image, a as usize))
                    } else {
                        None
                    };
                    let loc = if inout { Loc::IndAbs(a) } else { Loc::Abs(a) };
                    if b.constant && const_val.is_some() {
                        scope.vars.insert(
                            n.text.clone(),
                            VarInfo {
                                ty: t.clone(),
                                loc,
                                kind: b.kind,
                                constant: true,
                                const_val,
                                input_area: false,
                            },
                        );
                    }
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
        let pou_id = self.new_pou_name(shown);
        let id = self.funcs.len() as u32;
        self.funcs.push(FuncInfo {
            name: name.text.clone(),
            pou: pou_id,
            ret,
            result,
            params,
            locals,
            frame: (start, end - start),
        });
        self.fn_calls.push(Vec::new());
        self.code_fns.push(None);
        Ok(id)
    }

    pub(super) fn external(&mut self, n: &Name, d: &ast::VarDecl, scope: &Scope) -> R<VarInfo> {
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

    pub(super) fn declare_global(
        &mut self,
        b: &ast::VarBlock,
        d: &ast::VarDecl,
        scope: &Scope,
    ) -> R<()> {
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
    pub(super) fn declare_static(
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
            Some(repr_of(&t).load(&self.image, a as usize))
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

    pub(super) fn program_instance(&mut self, pou: &'a ast::Pou, inst: &str) -> R<ProgramInstance> {
        let pou_id = self.new_pou_name(&pou.name.text);
        let mut scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::Program,
            pou: pou_id,
            loops: 0,
            calls: Vec::new(),
            fb: None,
            for_vars: Vec::new(),
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

    /// The scope of a function block's body and methods: its members (relative to the
    /// instance) and its VAR_EXTERNALs.
    fn fb_scope(&mut self, id: u32, pou: &ast::Pou, pou_id: u32) -> R<Scope> {
        let members = self.fbs[id as usize].members.clone();
        let mut scope = Scope {
            vars: HashMap::new(),
            kind: PouKind::FunctionBlock,
            pou: pou_id,
            loops: 0,
            calls: Vec::new(),
            fb: Some(id),
            for_vars: Vec::new(),
        };
        for m in &members {
            let loc = if m.kind == VarKind::InOut {
                Loc::IndRel(m.offset)
            } else {
                Loc::Rel(m.offset)
            };
            let const_val = if m.constant && m.ty.scalar().is_some() {
                Some(repr_of(&m.ty).load(&self.fbs[id as usize].template, m.offset as usize))
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
            fb: None,
            for_vars: Vec::new(),
        };
        for b in pou.vars.iter().filter(|b| b.kind == VarKind::External) {
            for d in &b.decls {
                for nm in &d.names {
                    let g = self.external(nm, d, &empty)?;
                    scope.vars.insert(nm.text.clone(), g);
                }
            }
        }
        Ok(scope)
    }

    /// Lays out the METHODs and PROPERTYs of a function block (after its members are
    /// known), after those of its base: a method of the same name overrides the base's.
    pub(super) fn declare_methods(&mut self, n: &Name) -> R<()> {
        let id = self.fb_type(n)?;
        if !self.methods_declared.insert(id) {
            return Ok(());
        }
        let pou = self.fb_asts[&n.text];
        if let Some(b) = &pou.extends {
            self.declare_methods(b)?;
            // Inherit what the base declared after this block's layout copied its tables.
            let base = self.fbs[id as usize].base.map(|b| b as usize);
            if let Some(b) = base {
                self.fbs[id as usize].methods = self.fbs[b].methods.clone();
                self.fbs[id as usize].properties = self.fbs[b].properties.clone();
            }
        }
        let spelled =
            |c: &Self, t: &str| c.spelling.get(t).cloned().unwrap_or_else(|| t.to_string());
        let own_members_clash =
            |c: &Self, name: &str| c.fbs[id as usize].members.iter().any(|x| x.name == name);
        let mut own: Vec<String> = Vec::new();
        for m in &pou.methods {
            if own.contains(&m.name.text) || own_members_clash(self, &m.name.text) {
                return Err(self.e(
                    m.name.pos,
                    ErrorKind::Duplicate,
                    format!("'{}' is already declared in '{}'", m.name.text, n.text),
                ));
            }
            own.push(m.name.text.clone());
            let shown = format!("{}.{}", spelled(self, &n.text), spelled(self, &m.name.text));
            let f = self.callable(&m.name, &m.ret, &m.vars, &shown)?;
            let table = &mut self.fbs[id as usize].methods;
            match table.iter_mut().find(|x| x.0 == m.name.text) {
                Some(slot) => *slot = (m.name.text.clone(), f, m.private),
                None => table.push((m.name.text.clone(), f, m.private)),
            }
            self.method_asts.insert(f, (id, m));
            self.method_names.insert(m.name.text.clone());
        }
        for p in &pou.properties {
            if own.contains(&p.name.text) || own_members_clash(self, &p.name.text) {
                return Err(self.e(
                    p.name.pos,
                    ErrorKind::Duplicate,
                    format!("'{}' is already declared in '{}'", p.name.text, n.text),
                ));
            }
            own.push(p.name.text.clone());
            let empty = Scope {
                vars: HashMap::new(),
                kind: PouKind::Function,
                pou: 0,
                loops: 0,
                calls: Vec::new(),
                fb: None,
                for_vars: Vec::new(),
            };
            self.type_spec(&p.ty, None, &empty)?;
            let mut info = PropInfo {
                name: p.name.text.clone(),
                get: None,
                set: None,
                private: false,
            };
            for (acc, word) in [(&p.get, "GET"), (&p.set, "SET")] {
                let Some(m) = acc else { continue };
                let shown = format!(
                    "{}.{}.{word}",
                    spelled(self, &n.text),
                    spelled(self, &p.name.text)
                );
                let f = self.callable(&m.name, &m.ret, &m.vars, &shown)?;
                self.method_asts.insert(f, (id, m));
                info.private = m.private;
                if word == "GET" {
                    info.get = Some(f);
                } else {
                    info.set = Some(f);
                }
            }
            let table = &mut self.fbs[id as usize].properties;
            match table.iter_mut().find(|x| x.name == info.name) {
                Some(slot) => {
                    // An override may define only one accessor; the other is inherited.
                    slot.get = info.get.or(slot.get);
                    slot.set = info.set.or(slot.set);
                    slot.private = info.private;
                }
                None => table.push(info),
            }
        }
        Ok(())
    }

    /// An INTERFACE's id, declaring it (and the interfaces it extends) on first use.
    pub(super) fn iface(&mut self, n: &Name) -> R<u32> {
        match self.iface_by_name.get(&n.text) {
            Some(Lookup::Found(id)) => return Ok(*id),
            Some(Lookup::Busy) => {
                return Err(self.e(
                    n.pos,
                    ErrorKind::Invalid,
                    format!("interface '{}' extends itself", n.text),
                ));
            }
            _ => {}
        }
        let Some(ast) = self.iface_asts.get(&n.text).copied() else {
            return Err(self.e(
                n.pos,
                ErrorKind::Undeclared,
                format!("no INTERFACE named '{}'", n.text),
            ));
        };
        self.iface_by_name.insert(n.text.clone(), Lookup::Busy);
        let r = (|| {
            let mut extends = Vec::new();
            let mut methods = Vec::new();
            let mut properties = Vec::new();
            for e in &ast.extends {
                let id = self.iface(e)?;
                let base = &self.ifaces[id as usize];
                methods.extend(base.methods.iter().cloned());
                properties.extend(base.properties.iter().cloned());
                extends.push(id);
            }
            let empty = Scope {
                vars: HashMap::new(),
                kind: PouKind::Function,
                pou: 0,
                loops: 0,
                calls: Vec::new(),
                fb: None,
                for_vars: Vec::new(),
            };
            for m in &ast.methods {
                let ret = match &m.ret {
                    Some(TypeSpec::Named(t)) if t.text == "VOID" => None,
                    Some(t) => Some(self.type_spec(t, None, &empty)?.0),
                    None => None,
                };
                methods.push((m.name.text.clone(), ret));
            }
            for p in &ast.properties {
                let (t, _) = self.type_spec(&p.ty, None, &empty)?;
                properties.push((p.name.text.clone(), t));
            }
            Ok(IfaceInfo {
                name: ast.name.text.clone(),
                extends,
                methods,
                properties,
            })
        })();
        match r {
            Ok(info) => {
                let id = self.ifaces.len() as u32;
                self.ifaces.push(info);
                self.iface_by_name.insert(n.text.clone(), Lookup::Found(id));
                Ok(id)
            }
            Err(e) => {
                self.iface_by_name.insert(n.text.clone(), Lookup::Missing);
                Err(e)
            }
        }
    }

    /// Every method and property an implemented interface requires is there.
    pub(super) fn check_implements(&mut self, n: &Name) -> R<()> {
        let id = self.fb_type(n)?;
        let pou = self.fb_asts[&n.text];
        for (k, i) in pou.implements.iter().enumerate() {
            let Some(&iid) = self.fbs[id as usize].interfaces.get(k) else {
                continue;
            };
            let fb = &self.fbs[id as usize];
            let it = &self.ifaces[iid as usize];
            for (m, _) in &it.methods {
                if !fb.methods.iter().any(|x| &x.0 == m) {
                    return Err(self.e(
                        i.pos,
                        ErrorKind::Invalid,
                        format!(
                            "'{}' implements '{}' but has no METHOD '{m}': add it",
                            fb.name, it.name
                        ),
                    ));
                }
            }
            for (p, _) in &it.properties {
                if !fb.properties.iter().any(|x| &x.name == p) {
                    return Err(self.e(
                        i.pos,
                        ErrorKind::Invalid,
                        format!(
                            "'{}' implements '{}' but has no PROPERTY '{p}': add it",
                            fb.name, it.name
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Does function block `fb` extend `base` (or is it `base`)?
    pub(super) fn fb_extends(&self, fb: u32, base: u32) -> bool {
        let mut cur = Some(fb);
        while let Some(c) = cur {
            if c == base {
                return true;
            }
            cur = self.fbs.get(c as usize).and_then(|f| f.base);
        }
        false
    }

    /// Does interface `i` extend `target` (or is it `target`)?
    pub(super) fn iface_extends(&self, i: u32, target: u32) -> bool {
        i == target
            || self
                .ifaces
                .get(i as usize)
                .is_some_and(|x| x.extends.iter().any(|e| self.iface_extends(*e, target)))
    }

    /// Does function block `fb` (or a base of it) implement interface `i`?
    pub(super) fn fb_implements(&self, fb: u32, i: u32) -> bool {
        let mut cur = Some(fb);
        while let Some(c) = cur {
            let Some(f) = self.fbs.get(c as usize) else {
                return false;
            };
            if f.interfaces.iter().any(|x| self.iface_extends(*x, i)) {
                return true;
            }
            cur = f.base;
        }
        false
    }

    /// Compiles a METHOD: the function block's members relative to the instance, the
    /// method's own variables in its static frame.
    pub(super) fn method_body(&mut self, fid: u32) -> R<()> {
        let (fb, m) = self.method_asts[&fid];
        let fb_name = self.fbs[fb as usize].name.clone();
        let pou = self.fb_asts[&fb_name];
        let (locals, pou_id, frame, result, aggregate, repr) = {
            let f = &self.funcs[fid as usize];
            (
                f.locals.clone(),
                f.pou,
                f.frame,
                f.result,
                f.ret.as_ref().is_some_and(|t| t.scalar().is_none()),
                f.ret.as_ref().map_or(Repr::U64, repr_of),
            )
        };
        let mut scope = self.fb_scope(fb, pou, pou_id)?;
        scope.kind = PouKind::Function;
        let prefix = format!("{}.", m.name.text);
        let inst: Vec<(String, VarInfo)> = scope
            .vars
            .iter()
            .filter_map(|(k, v)| k.strip_prefix(&prefix).map(|n| (n.to_string(), v.clone())))
            .collect();
        scope.vars.extend(inst);
        scope.vars.extend(locals);
        let stmts = self.block(&m.body, &mut scope)?;
        self.fn_calls[fid as usize] = std::mem::take(&mut scope.calls);
        let values = self.image[frame.0 as usize..(frame.0 + frame.1) as usize]
            .to_vec()
            .into_boxed_slice();
        self.code_fns[fid as usize] = Some(vm::Function {
            body: vm::Body {
                pou: pou_id,
                reinit: Some((frame.0, values)),
                stmts,
            },
            result,
            repr,
            aggregate,
        });
        Ok(())
    }

    pub(super) fn fb_body(&mut self, n: &Name) -> R<()> {
        let id = self.fb_type(n)?;
        let pou = self.fb_asts[&n.text];
        let pou_id = self.new_pou_name(&pou.name.text);
        let members = self.fbs[id as usize].members.clone();
        let mut scope = self.fb_scope(id, pou, pou_id)?;
        let stmts = self.block(&pou.body, &mut scope)?;
        // VAR_TEMP members are re-initialised on every call.
        let own_start = self.fbs[id as usize].own_start;
        let temps: Vec<&Member> = members
            .iter()
            .filter(|m| m.kind == VarKind::Temp && m.offset >= own_start)
            .collect();
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

    pub(super) fn fn_body(&mut self, n: &Name) -> R<()> {
        let id = self.func(n)?;
        let pou = self.fn_asts[&n.text];
        let (vars, pou_id, frame, result, aggregate, repr) = {
            let f = &self.funcs[id as usize];
            (
                f.locals.clone(),
                f.pou,
                f.frame,
                f.result,
                f.ret.as_ref().is_some_and(|t| t.scalar().is_none()),
                f.ret.as_ref().map_or(Repr::U64, repr_of),
            )
        };
        let mut scope = Scope {
            vars,
            kind: PouKind::Function,
            pou: pou_id,
            loops: 0,
            calls: Vec::new(),
            fb: None,
            for_vars: Vec::new(),
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
            repr,
            aggregate,
        });
        Ok(())
    }
}

/// A function block's variable blocks in the order of its instance's layout, each with the
/// prefix of its members' names: VAR_TEMP members go last, so the slots re-initialised per
/// call are contiguous; a METHOD's VAR_INST lives in the instance as `METHOD.NAME`.
fn fb_member_blocks(pou: &ast::Pou) -> impl Iterator<Item = (String, &ast::VarBlock)> {
    let inst_vars: Vec<(String, &ast::VarBlock)> = pou
        .methods
        .iter()
        .flat_map(|m| {
            m.vars
                .iter()
                .filter(|b| b.kind == VarKind::Inst)
                .map(move |b| (format!("{}.", m.name.text), b))
        })
        .collect();
    pou.vars
        .iter()
        .filter(|b| b.kind != VarKind::Temp)
        .map(|b| (String::new(), b))
        .chain(inst_vars)
        .chain(
            pou.vars
                .iter()
                .filter(|b| b.kind == VarKind::Temp)
                .map(|b| (String::new(), b)),
        )
}
