//! Calls of functions and function blocks: argument binding.

use super::*;

/// Bound call arguments: whether they may be written straight into the parameters, the
/// inputs and the `=>` outputs.
type BoundArgs = (bool, Box<[ArgIn]>, Box<[ArgOut]>);

impl<'a> Compiler<'a> {
    // ---------------------------------------------------------------- calls

    pub(super) fn call_stmt(
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
        // `instance.method(...)` as a statement.
        if let Some(ast::Part::Field(m)) = target.parts.last() {
            let prefix = Access {
                root: target.root.clone(),
                parts: target.parts[..target.parts.len() - 1].to_vec(),
            };
            let is_method = match self.access(&prefix, sc) {
                Ok(lv) => {
                    matches!(lv.ty, Type::Fb(id) if self.fbs[id as usize].methods.iter().any(|x| x.0 == m.text))
                }
                Err(_) => false,
            };
            if is_method {
                let te = self.method_call(&prefix, m, args, sc, pos)?;
                return Ok(StmtKind::Eval(te.e));
            }
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
        let (direct, ins, outs) = self.bind_args(&fb_name, &members, args, sc, pos)?;
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
    pub(super) fn bind_args(
        &mut self,
        pou: &str,
        params: &[Member],
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<BoundArgs> {
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
        Ok((!calls_user, ins.into_boxed_slice(), outs.into_boxed_slice()))
    }

    pub(super) fn arg_in(
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

    pub(super) fn call_expr(
        &mut self,
        name: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
        expect: Option<&Type>,
    ) -> R<TE> {
        if let Some(id) = self.func_id(name)? {
            let (fname, params, ret) = {
                let f = &self.funcs[id as usize];
                (f.name.clone(), f.params.clone(), f.ret.clone())
            };
            let (direct, ins, outs) = self.bind_args(&fname, &params, args, sc, pos)?;
            sc.calls.push(id);
            let call = vm::Expr::Call(Box::new(FnCall {
                func: id,
                direct,
                args: ins,
                outs,
            }));
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
        // A method of the function block this body belongs to, called without instance.
        if let Some(fb) = sc.fb {
            if let Some(&(_, fid, _)) = self.fbs[fb as usize]
                .methods
                .iter()
                .find(|x| x.0 == name.text)
            {
                return self.method_call_on(Place::Rel(0), fb, fid, name, args, sc, pos);
            }
        }
        crate::builtins::call(self, name, args, sc, pos, expect)
    }

    /// `prefix.method(args)`: prefix must be an instance of a function block with that
    /// method (PRIVATE methods only from inside the block).
    pub(super) fn method_call(
        &mut self,
        prefix: &Access,
        m: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<TE> {
        let lv = self.access(prefix, sc)?;
        let Type::Fb(fb) = lv.ty else {
            return Err(self.e(
                m.pos,
                ErrorKind::TypeMismatch,
                format!("'{}' is not a function block instance", prefix.root.text),
            ));
        };
        let Some(&(_, fid, private)) = self.fbs[fb as usize].methods.iter().find(|x| x.0 == m.text)
        else {
            return Err(self.e(
                m.pos,
                ErrorKind::Undeclared,
                format!("{} has no method '{}'", self.fbs[fb as usize].name, m.text),
            ));
        };
        if private && sc.fb != Some(fb) {
            return Err(self.e(
                m.pos,
                ErrorKind::Invalid,
                format!(
                    "method '{}' is PRIVATE to {}",
                    m.text, self.fbs[fb as usize].name
                ),
            ));
        }
        let instance = self.place(lv);
        self.method_call_on(instance, fb, fid, m, args, sc, pos)
    }

    #[allow(clippy::too_many_arguments)]
    fn method_call_on(
        &mut self,
        instance: Place,
        fb: u32,
        fid: u32,
        m: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<TE> {
        let (params, ret) = {
            let f = &self.funcs[fid as usize];
            (f.params.clone(), f.ret.clone())
        };
        let shown = format!("{}.{}", self.fbs[fb as usize].name, m.text);
        let (direct, ins, outs) = self.bind_args(&shown, &params, args, sc, pos)?;
        sc.calls.push(fid);
        let call = FnCall {
            func: fid,
            direct,
            args: ins,
            outs,
        };
        let e = vm::Expr::CallMethod(Box::new(vm::MethodCall { instance, call }));
        Ok(TE {
            ty: Ty::T(ret.unwrap_or(Type::BOOL)),
            e,
        })
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
