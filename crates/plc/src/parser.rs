//! Recursive-descent parser from tokens to the syntax tree.

use crate::ast::*;
use crate::error::{CompileError, ErrorKind, Pos};
use crate::lexer::{Tok, Token};

/// Deepest nesting of sub-expressions (parentheses, unary operators, arguments), and of
/// statements, accepted.
const MAX_EXPR_DEPTH: u32 = 64;
const MAX_STMT_DEPTH: u32 = 32;
/// Deepest expression tree accepted: the nesting plus the operators of a left-to-right
/// chain (`a + b - c + ...` is a tree as deep as its operators; AND/OR/XOR chains are
/// balanced). Parsing, compiling and running recurse along the tree; this limit and the
/// ones above keep the worst case inside 1 MiB of stack even in debug builds
/// (tests/fuzz.rs checks it).
const MAX_TREE_DEPTH: u32 = 128;

pub(crate) struct Parser<'a> {
    toks: &'a [Token],
    i: usize,
    file: &'a str,
    depth: u32,
    /// Depth of the expression tree being built (nesting and chains).
    tree: u32,
    stmt_depth: u32,
}

type PResult<T> = Result<T, CompileError>;

pub(crate) fn parse(toks: &[Token], file: &str) -> PResult<Unit> {
    let mut p = Parser {
        toks,
        i: 0,
        file,
        depth: 0,
        tree: 0,
        stmt_depth: 0,
    };
    p.unit()
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Ident(s) => format!("'{s}'"),
        Tok::Int(v) => format!("number {v}"),
        Tok::Real(v) => format!("number {v}"),
        Tok::Time(_) => "duration literal".into(),
        Tok::Moment(..) => "date or time-of-day literal".into(),
        Tok::Str(_) => "string literal".into(),
        Tok::WStr(_) => "WSTRING literal".into(),
        Tok::TypedPrefix(s) => format!("'{s}#'"),
        Tok::Direct(d) => format!("'{d}'"),
        Tok::Eof => "end of file".into(),
        other => {
            let s = match other {
                Tok::Assign => ":=",
                Tok::Output => "=>",
                Tok::Colon => ":",
                Tok::Semi => ";",
                Tok::Comma => ",",
                Tok::Dot => ".",
                Tok::DotDot => "..",
                Tok::LParen => "(",
                Tok::RParen => ")",
                Tok::LBracket => "[",
                Tok::RBracket => "]",
                Tok::Plus => "+",
                Tok::Minus => "-",
                Tok::Star => "*",
                Tok::Power => "**",
                Tok::Slash => "/",
                Tok::Amp => "&",
                Tok::Eq => "=",
                Tok::Ne => "<>",
                Tok::Lt => "<",
                Tok::Le => "<=",
                Tok::Gt => ">",
                Tok::Ge => ">=",
                Tok::Caret => "^",
                _ => "?",
            };
            format!("'{s}'")
        }
    }
}

const RESERVED: &[&str] = &[
    "IF",
    "THEN",
    "ELSIF",
    "ELSE",
    "END_IF",
    "CASE",
    "OF",
    "END_CASE",
    "FOR",
    "TO",
    "BY",
    "DO",
    "END_FOR",
    "WHILE",
    "END_WHILE",
    "REPEAT",
    "UNTIL",
    "END_REPEAT",
    "EXIT",
    "RETURN",
    "CONTINUE",
    "VAR",
    "END_VAR",
    "VAR_INPUT",
    "VAR_OUTPUT",
    "VAR_IN_OUT",
    "VAR_GLOBAL",
    "VAR_EXTERNAL",
    "VAR_TEMP",
    "PROGRAM",
    "END_PROGRAM",
    "FUNCTION",
    "END_FUNCTION",
    "FUNCTION_BLOCK",
    "END_FUNCTION_BLOCK",
    "TYPE",
    "END_TYPE",
    "STRUCT",
    "END_STRUCT",
    "ARRAY",
    "AND",
    "OR",
    "XOR",
    "NOT",
    "MOD",
    "TRUE",
    "FALSE",
    "CONFIGURATION",
    "END_CONFIGURATION",
    "RESOURCE",
    "END_RESOURCE",
    "TASK",
    "WITH",
    "AT",
    "CONSTANT",
    "RETAIN",
    "NON_RETAIN",
    "METHOD",
    "END_METHOD",
    "PROPERTY",
    "END_PROPERTY",
    "INTERFACE",
    "END_INTERFACE",
    "END_GET",
    "END_SET",
    "VAR_INST",
    "EXTENDS",
    "IMPLEMENTS",
    "END_STRUCT",
    "END_UNION",
];

/// Words that end a block: meeting one where a statement or declaration should start
/// means a block above was not closed.
/// The statement a closing word belongs to: `END_IF`, `ELSIF`, `ELSE` to IF, and so on.
fn statement_closed_by(word: &str) -> Option<&'static str> {
    Some(match word {
        "END_IF" | "ELSIF" => "IF",
        "ELSE" => "IF or CASE",
        "END_CASE" => "CASE",
        "END_FOR" => "FOR",
        "END_WHILE" => "WHILE",
        "END_REPEAT" | "UNTIL" => "REPEAT",
        _ => return None,
    })
}

fn closes_a_block(word: &str) -> bool {
    word.starts_with("END_")
        || matches!(
            word,
            "ELSE"
                | "ELSIF"
                | "UNTIL"
                | "PROGRAM"
                | "FUNCTION"
                | "FUNCTION_BLOCK"
                | "TYPE"
                | "METHOD"
                | "PROPERTY"
                | "INTERFACE"
                | "CONFIGURATION"
                | "VAR_GLOBAL"
        )
}

impl Parser<'_> {
    fn peek(&self) -> &Tok {
        &self.toks[self.i.min(self.toks.len() - 1)].kind
    }
    fn peek_at(&self, k: usize) -> &Tok {
        &self.toks[(self.i + k).min(self.toks.len() - 1)].kind
    }
    fn pos(&self) -> Pos {
        self.toks[self.i.min(self.toks.len() - 1)].pos
    }
    fn bump(&mut self) -> Tok {
        let t = self.peek().clone();
        if self.i < self.toks.len() - 1 {
            self.i += 1;
        }
        t
    }
    fn err(&self, msg: impl Into<String>) -> CompileError {
        CompileError::new(self.file, self.pos(), ErrorKind::Syntax, msg)
    }
    fn unexpected(&self, wanted: &str) -> CompileError {
        self.err(format!(
            "expected {wanted}, found {}",
            describe(self.peek())
        ))
    }
    /// `"END_IF expected to close the IF at 12:5, found 'END_PROGRAM'"`.
    fn unclosed(&self, end: &str, opener: &str, at: Pos) -> CompileError {
        self.err(format!(
            "{end} expected to close the {opener} at {}:{}, found {}",
            at.line,
            at.col,
            describe(self.peek())
        ))
    }
    /// The error at a word that closes a block while the statements of `opener` (at `at`,
    /// closed by `end`) are read: `end` is missing, or, in a POU's body, the word closes a
    /// statement that is not open (an extra END_IF). Apart, so that the recursion through
    /// statements keeps small frames.
    #[cold]
    #[inline(never)]
    fn block_end_error(&self, end: &str, opener: &str, at: Pos) -> CompileError {
        let in_statement = matches!(opener, "IF" | "CASE" | "FOR" | "WHILE" | "REPEAT");
        if let (false, Tok::Ident(word)) = (in_statement, self.peek()) {
            if let Some(statement) = statement_closed_by(word) {
                return self.err(format!(
                    "{word} without an open {statement}: remove it or add the {statement} \
                     it closes (the {opener} at {}:{} ends with {end})",
                    at.line, at.col
                ));
            }
        }
        self.unclosed(end, opener, at)
    }
    /// Expects `)` or `]` closing the `(` or `[` at `at`.
    fn expect_close(&mut self, close: &Tok, at: Pos) -> PResult<()> {
        if self.eat(close) {
            return Ok(());
        }
        let open = match close {
            Tok::RBracket => "'['",
            _ => "'('",
        };
        Err(self.unclosed(&describe(close), open, at))
    }
    /// Expects keyword `kw` that continues the construct `what` started at `at`.
    fn expect_kw_in(&mut self, kw: &str, what: &str, at: Pos) -> PResult<()> {
        if self.eat_kw(kw) {
            Ok(())
        } else {
            Err(self.err(format!(
                "{kw} expected in the {what} at {}:{}, found {}",
                at.line,
                at.col,
                describe(self.peek())
            )))
        }
    }
    /// True when the cursor is at end of file or at a word that closes some block.
    fn at_block_end(&self) -> bool {
        match self.peek() {
            Tok::Eof => true,
            Tok::Ident(s) => closes_a_block(s),
            _ => false,
        }
    }
    fn is_kw(&self, kw: &str) -> bool {
        matches!(self.peek(), Tok::Ident(s) if s == kw)
    }
    fn eat_kw(&mut self, kw: &str) -> bool {
        if self.is_kw(kw) {
            self.bump();
            true
        } else {
            false
        }
    }
    fn eat(&mut self, t: &Tok) -> bool {
        if self.peek() == t {
            self.bump();
            true
        } else {
            false
        }
    }
    fn expect(&mut self, t: &Tok) -> PResult<()> {
        if self.eat(t) {
            Ok(())
        } else {
            Err(self.unexpected(&describe(t)))
        }
    }
    fn name(&mut self) -> PResult<Name> {
        let pos = self.pos();
        match self.peek() {
            Tok::Ident(s) if !RESERVED.contains(&s.as_str()) => {
                let text = s.clone();
                self.bump();
                Ok(Name { text, pos })
            }
            _ => Err(self.unexpected("a name")),
        }
    }
    fn enter(&mut self) -> PResult<()> {
        self.depth += 1;
        if self.depth > MAX_EXPR_DEPTH {
            return Err(self.err(format!("expression nested more than {MAX_EXPR_DEPTH} deep")));
        }
        self.deeper_tree()
    }

    fn leave(&mut self) {
        self.depth -= 1;
        self.tree -= 1;
    }

    /// One more level of the expression tree (an operator of a chain, or a nesting).
    fn deeper_tree(&mut self) -> PResult<()> {
        self.tree += 1;
        if self.tree > MAX_TREE_DEPTH {
            return Err(self.err(format!(
                "expression too long: a tree more than {MAX_TREE_DEPTH} operators deep \
                 (split it with intermediate variables)"
            )));
        }
        Ok(())
    }

    fn unit(&mut self) -> PResult<Unit> {
        let mut u = Unit::default();
        loop {
            match self.peek() {
                Tok::Eof => return Ok(u),
                Tok::Ident(s) => {
                    match s.as_str() {
                        "TYPE" => {
                            let at = self.pos();
                            self.bump();
                            while !self.eat_kw("END_TYPE") {
                                if self.at_block_end() {
                                    return Err(self.unclosed("END_TYPE", "TYPE", at));
                                }
                                u.types.push(self.type_decl()?);
                            }
                            self.eat(&Tok::Semi);
                        }
                        "INTERFACE" => u.interfaces.push(self.interface()?),
                        "PROGRAM" => u.pous.push(self.pou(PouKind::Program, "END_PROGRAM")?),
                        "FUNCTION" => u.pous.push(self.pou(PouKind::Function, "END_FUNCTION")?),
                        "FUNCTION_BLOCK" => u
                            .pous
                            .push(self.pou(PouKind::FunctionBlock, "END_FUNCTION_BLOCK")?),
                        "VAR_GLOBAL" => u.globals.push(self.var_block()?),
                        "CONFIGURATION" => u.configs.push(self.config()?),
                        "LIBRARY" => {
                            // A CODESYS 2.3 export ends with the libraries the project
                            // links (`LIBRARY Standard.lib ... END_LIBRARY`): names, no code.
                            let at = self.pos();
                            self.bump();
                            while !self.eat_kw("END_LIBRARY") {
                                if self.peek() == &Tok::Eof {
                                    return Err(self.unclosed("END_LIBRARY", "LIBRARY", at));
                                }
                                self.bump();
                            }
                        }
                        w if w.starts_with("END_") || statement_closed_by(w).is_some() => {
                            return Err(self.err(format!(
                                "{w} closes nothing here: no block is open (a file holds \
                                 TYPE, PROGRAM, FUNCTION, FUNCTION_BLOCK, INTERFACE, VAR_GLOBAL \
                                 or CONFIGURATION blocks; is there one END_... too many?)"
                            )));
                        }
                        _ => return Err(self.unexpected(
                            "TYPE, PROGRAM, FUNCTION, FUNCTION_BLOCK, INTERFACE, VAR_GLOBAL or CONFIGURATION",
                        )),
                    }
                }
                Tok::Semi => {
                    // `END_FUNCTION_BLOCK;` and the like, as some exports write them.
                    self.bump();
                }
                _ => {
                    return Err(self.unexpected(
                        "TYPE, PROGRAM, FUNCTION, FUNCTION_BLOCK, INTERFACE, VAR_GLOBAL or CONFIGURATION",
                    ));
                }
            }
        }
    }

    fn type_decl(&mut self) -> PResult<TypeDecl> {
        let name = self.name()?;
        self.expect(&Tok::Colon)?;
        let spec = self.type_spec()?;
        let init = if self.eat(&Tok::Assign) {
            Some(self.declared_init()?)
        } else {
            None
        };
        // CODESYS writes `END_STRUCT` straight before `END_TYPE`.
        if !self.eat(&Tok::Semi) && !self.is_kw("END_TYPE") {
            return Err(self.unexpected("';' after the type declaration"));
        }
        Ok(TypeDecl { name, spec, init })
    }

    fn type_spec(&mut self) -> PResult<TypeSpec> {
        let pos = self.pos();
        if self.eat_kw("POINTER") {
            self.expect_kw_in("TO", "POINTER TO declaration", pos)?;
            return Ok(TypeSpec::Pointer(Box::new(self.type_spec()?)));
        }
        if self.eat_kw("REFERENCE") {
            self.expect_kw_in("TO", "REFERENCE TO declaration", pos)?;
            return Ok(TypeSpec::Reference(Box::new(self.type_spec()?), pos));
        }
        if self.eat_kw("REF_TO") {
            return Ok(TypeSpec::Reference(Box::new(self.type_spec()?), pos));
        }
        if self.eat_kw("ARRAY") {
            let open = self.pos();
            self.expect(&Tok::LBracket)?;
            let mut dims = Vec::new();
            loop {
                let lo = self.expr()?;
                self.expect(&Tok::DotDot)?;
                let hi = self.expr()?;
                dims.push((lo, hi));
                if !self.eat(&Tok::Comma) {
                    break;
                }
            }
            self.expect_close(&Tok::RBracket, open)?;
            self.expect_kw_in("OF", "ARRAY declaration", pos)?;
            let elem = self.type_spec()?;
            return Ok(TypeSpec::Array {
                dims,
                elem: Box::new(elem),
                pos,
            });
        }
        for (open, close, union) in [
            ("STRUCT", "END_STRUCT", false),
            ("UNION", "END_UNION", true),
        ] {
            if self.eat_kw(open) {
                let mut fields = Vec::new();
                while !self.eat_kw(close) {
                    if self.at_block_end() {
                        return Err(self.unclosed(close, open, pos));
                    }
                    fields.push(self.var_decl(false)?);
                }
                return Ok(TypeSpec::Struct { fields, union, pos });
            }
        }
        if self.peek() == &Tok::LParen {
            let open = self.pos();
            self.bump();
            let mut values = Vec::new();
            loop {
                let n = self.name()?;
                let v = if self.eat(&Tok::Assign) {
                    Some(self.expr()?)
                } else {
                    None
                };
                values.push((n, v));
                if !self.eat(&Tok::Comma) {
                    break;
                }
            }
            self.expect_close(&Tok::RParen, open)?;
            // CODESYS and TwinCAT write the base type after the values: `(A, B) UINT`.
            let base = match self.peek() {
                Tok::Ident(s) if !RESERVED.contains(&s.as_str()) => Some(self.name()?),
                _ => None,
            };
            return Ok(TypeSpec::Enum { values, base, pos });
        }
        if self.is_kw("STRING") || self.is_kw("WSTRING") {
            let wide = self.is_kw("WSTRING");
            self.bump();
            let open = self.pos();
            let len = if self.eat(&Tok::LBracket) {
                let e = self.expr()?;
                self.expect_close(&Tok::RBracket, open)?;
                Some(e)
            } else if self.peek() == &Tok::LParen {
                self.bump();
                let e = self.expr()?;
                self.expect_close(&Tok::RParen, open)?;
                Some(e)
            } else {
                None
            };
            return Ok(TypeSpec::String { len, wide, pos });
        }
        let base = self.name()?;
        if self.peek() == &Tok::LParen {
            // Subrange `INT(0..100)` or typed enum `INT (A := 1, B := 2)`.
            let open = self.pos();
            let save = self.i;
            self.bump();
            if matches!(self.peek(), Tok::Ident(_))
                && matches!(self.peek_at(1), Tok::Assign | Tok::Comma | Tok::RParen)
            {
                self.i = save;
                if let TypeSpec::Enum { values, pos, .. } = self.type_spec()? {
                    return Ok(TypeSpec::Enum {
                        values,
                        base: Some(base),
                        pos,
                    });
                }
            }
            let low = self.expr()?;
            self.expect(&Tok::DotDot)?;
            let high = self.expr()?;
            self.expect_close(&Tok::RParen, open)?;
            return Ok(TypeSpec::Subrange { base, low, high });
        }
        Ok(TypeSpec::Named(base))
    }

    /// A declaration's initial value: as [`Self::init`], or CODESYS 2.3's array values
    /// without brackets, `1, 3, 7, 15` and `2(0), 5`, up to the `;`.
    fn declared_init(&mut self) -> PResult<Init> {
        let pos = self.pos();
        let first = self.array_item()?;
        if first.0.is_none() && self.peek() != &Tok::Comma {
            return Ok(first.1);
        }
        let mut items = vec![first];
        while self.eat(&Tok::Comma) {
            items.push(self.array_item()?);
        }
        Ok(Init::Array(items, pos))
    }

    /// One element of an array's initial value: a value, or `n(value)` (n times).
    fn array_item(&mut self) -> PResult<(Option<Expr>, Init)> {
        let pos = self.pos();
        if matches!(self.peek(), Tok::Int(_)) && self.peek_at(1) == &Tok::LParen {
            let count = self.primary()?;
            let open = self.pos();
            self.expect(&Tok::LParen)?;
            let v = if self.peek() == &Tok::RParen {
                None
            } else {
                Some(self.init()?)
            };
            self.expect_close(&Tok::RParen, open)?;
            return Ok((Some(count), v.unwrap_or(Init::Array(Vec::new(), pos))));
        }
        Ok((None, self.init()?))
    }

    fn init(&mut self) -> PResult<Init> {
        let pos = self.pos();
        if self.eat(&Tok::LBracket) {
            let mut items = Vec::new();
            if !self.eat(&Tok::RBracket) {
                loop {
                    items.push(self.array_item()?);
                    if !self.eat(&Tok::Comma) {
                        break;
                    }
                }
                self.expect_close(&Tok::RBracket, pos)?;
            }
            return Ok(Init::Array(items, pos));
        }
        if self.peek() == &Tok::LParen
            && matches!(self.peek_at(1), Tok::Ident(_))
            && self.peek_at(2) == &Tok::Assign
        {
            self.bump();
            let mut items = Vec::new();
            loop {
                let n = self.name()?;
                self.expect(&Tok::Assign)?;
                items.push((n, self.init()?));
                if !self.eat(&Tok::Comma) {
                    break;
                }
            }
            self.expect_close(&Tok::RParen, pos)?;
            return Ok(Init::Struct(items, pos));
        }
        Ok(Init::Expr(self.expr()?))
    }

    fn var_block(&mut self) -> PResult<VarBlock> {
        let kind = match self.peek() {
            Tok::Ident(s) => match s.as_str() {
                "VAR" => VarKind::Local,
                "VAR_INPUT" => VarKind::Input,
                "VAR_OUTPUT" => VarKind::Output,
                "VAR_IN_OUT" => VarKind::InOut,
                "VAR_GLOBAL" => VarKind::Global,
                "VAR_EXTERNAL" => VarKind::External,
                "VAR_TEMP" => VarKind::Temp,
                "VAR_INST" => VarKind::Inst,
                _ => return Err(self.unexpected("a VAR block")),
            },
            _ => return Err(self.unexpected("a VAR block")),
        };
        let (opener, at) = (describe(self.peek()), self.pos());
        let opener = opener.trim_matches('\'').to_string();
        self.bump();
        let mut constant = false;
        let mut retain = false;
        loop {
            if self.eat_kw("CONSTANT") {
                constant = true;
            } else if self.eat_kw("RETAIN") || self.eat_kw("PERSISTENT") {
                retain = true;
            } else if self.eat_kw("NON_RETAIN") {
                retain = false;
            } else {
                break;
            }
        }
        let mut decls = Vec::new();
        while !self.eat_kw("END_VAR") {
            // A statement where a declaration should be: the block was left open.
            let statement = matches!(
                self.peek(),
                Tok::Ident(s) if matches!(
                    s.as_str(),
                    "IF" | "CASE" | "FOR" | "WHILE" | "REPEAT" | "RETURN" | "EXIT" | "CONTINUE"
                )
            ) || (matches!(self.peek(), Tok::Ident(_))
                && matches!(
                    self.peek_at(1),
                    Tok::Assign | Tok::LParen | Tok::Dot | Tok::LBracket | Tok::Caret
                ));
            if self.at_block_end() || self.is_var_block_start() || statement {
                return Err(self.unclosed("END_VAR", &opener, at));
            }
            decls.push(self.var_decl(true)?);
        }
        Ok(VarBlock {
            kind,
            constant,
            retain,
            decls,
        })
    }

    fn var_decl(&mut self, allow_at: bool) -> PResult<VarDecl> {
        let start = self.pos();
        let mut names = vec![self.name()?];
        while self.eat(&Tok::Comma) {
            names.push(self.name()?);
        }
        let mut at = None;
        if allow_at && self.eat_kw("AT") {
            let pos = self.pos();
            match self.bump() {
                Tok::Direct(d) => at = Some((d, pos)),
                _ => {
                    self.i -= 1;
                    return Err(self.unexpected("a direct address like %IX0.0"));
                }
            }
        }
        if !self.eat(&Tok::Colon) {
            return Err(self.err(format!(
                "':' and a type expected after the name in the declaration at {}:{}, found {}",
                start.line,
                start.col,
                describe(self.peek())
            )));
        }
        let ty = self.type_spec()?;
        let init = if self.eat(&Tok::Assign) {
            Some(self.declared_init()?)
        } else {
            None
        };
        if !self.eat(&Tok::Semi) {
            return Err(self.err(format!(
                "';' expected to end the declaration at {}:{}, found {}",
                start.line,
                start.col,
                describe(self.peek())
            )));
        }
        Ok(VarDecl {
            names,
            at,
            ty,
            init,
        })
    }

    fn is_var_block_start(&self) -> bool {
        matches!(self.peek(), Tok::Ident(s) if matches!(s.as_str(), "VAR" | "VAR_INPUT" | "VAR_OUTPUT" | "VAR_IN_OUT" | "VAR_GLOBAL" | "VAR_EXTERNAL" | "VAR_TEMP" | "VAR_INST"))
    }

    /// Access and inheritance modifiers; returns true for PRIVATE or PROTECTED.
    fn modifiers(&mut self) -> bool {
        let mut private = false;
        loop {
            if self.eat_kw("PUBLIC")
                || self.eat_kw("INTERNAL")
                || self.eat_kw("FINAL")
                || self.eat_kw("ABSTRACT")
            {
                continue;
            }
            if self.eat_kw("PRIVATE") || self.eat_kw("PROTECTED") {
                private = true;
                continue;
            }
            return private;
        }
    }

    fn pou(&mut self, kind: PouKind, end: &str) -> PResult<Pou> {
        let at = self.pos();
        let opener = match kind {
            PouKind::Program => "PROGRAM",
            PouKind::Function => "FUNCTION",
            PouKind::FunctionBlock => "FUNCTION_BLOCK",
        };
        self.bump();
        if kind == PouKind::FunctionBlock {
            self.modifiers();
        }
        let name = self.name()?;
        let ret = if kind == PouKind::Function {
            // A function without `: type` returns nothing (3rd edition).
            if self.eat(&Tok::Colon) {
                Some(self.type_spec()?)
            } else {
                None
            }
        } else {
            None
        };
        let mut extends = None;
        let mut implements = Vec::new();
        if kind == PouKind::FunctionBlock {
            if self.eat_kw("EXTENDS") {
                extends = Some(self.name()?);
            }
            if self.eat_kw("IMPLEMENTS") {
                loop {
                    implements.push(self.name()?);
                    if !self.eat(&Tok::Comma) {
                        break;
                    }
                }
            }
        }
        let mut vars = Vec::new();
        while self.is_var_block_start() {
            vars.push(self.var_block()?);
        }
        let mut methods = Vec::new();
        let mut properties = Vec::new();
        let fb = kind == PouKind::FunctionBlock;
        let mut members = |p: &mut Self| -> PResult<()> {
            loop {
                if p.is_kw("METHOD") {
                    methods.push(p.method(false)?);
                } else if p.is_kw("PROPERTY") {
                    properties.push(p.property(false)?);
                } else {
                    return Ok(());
                }
            }
        };
        if fb {
            members(self)?;
        }
        // The body; in a function block, METHODs and PROPERTYs may also follow it.
        let ends: &[&str] = if fb {
            &[end, "METHOD", "PROPERTY"]
        } else {
            &[end]
        };
        let body = self.stmts(ends, opener, at)?;
        if fb {
            members(self)?;
        }
        if !self.eat_kw(end) {
            return Err(self.unclosed(end, opener, at));
        }
        Ok(Pou {
            kind,
            name,
            extends,
            implements,
            properties,
            ret,
            vars,
            methods,
            body,
        })
    }

    /// A METHOD; `prototype` (in an INTERFACE) has declarations but no body.
    fn method(&mut self, prototype: bool) -> PResult<Method> {
        let at = self.pos();
        self.bump();
        let private = self.modifiers();
        let name = self.name()?;
        let ret = if self.eat(&Tok::Colon) {
            Some(self.type_spec()?)
        } else {
            None
        };
        self.eat(&Tok::Semi);
        let mut vars = Vec::new();
        while self.is_var_block_start() {
            vars.push(self.var_block()?);
        }
        let body = if prototype {
            Vec::new()
        } else {
            self.stmts(&["END_METHOD"], "METHOD", at)?
        };
        if !self.eat_kw("END_METHOD") {
            return Err(self.unclosed("END_METHOD", "METHOD", at));
        }
        self.eat(&Tok::Semi);
        Ok(Method {
            name,
            ret,
            vars,
            body,
            private,
        })
    }

    /// `PROPERTY name : type  GET ... END_GET  SET ... END_SET  END_PROPERTY`.
    fn property(&mut self, prototype: bool) -> PResult<Property> {
        let at = self.pos();
        self.bump();
        let private = self.modifiers();
        let name = self.name()?;
        self.expect(&Tok::Colon)?;
        let ty = self.type_spec()?;
        self.eat(&Tok::Semi);
        let mut get = None;
        let mut set = None;
        let accessor = |setter: bool, vars: Vec<VarBlock>, body: Vec<Stmt>| Method {
            name: name.clone(),
            ret: if setter { None } else { Some(ty.clone()) },
            vars: if setter {
                let mut v = vec![VarBlock {
                    kind: VarKind::Input,
                    constant: false,
                    retain: false,
                    decls: vec![VarDecl {
                        names: vec![name.clone()],
                        at: None,
                        ty: ty.clone(),
                        init: None,
                    }],
                }];
                v.extend(vars);
                v
            } else {
                vars
            },
            body,
            private,
        };
        loop {
            let part_at = self.pos();
            let (setter, end, word) = if self.eat_kw("GET") {
                (false, "END_GET", "GET")
            } else if self.eat_kw("SET") {
                (true, "END_SET", "SET")
            } else {
                break;
            };
            let mut vars = Vec::new();
            while self.is_var_block_start() {
                vars.push(self.var_block()?);
            }
            let body = self.stmts(&[end], word, part_at)?;
            if !self.eat_kw(end) {
                return Err(self.unclosed(end, word, part_at));
            }
            self.eat(&Tok::Semi);
            let m = accessor(setter, vars, body);
            if setter {
                set = Some(m);
            } else {
                get = Some(m);
            }
        }
        if !self.eat_kw("END_PROPERTY") {
            return Err(self.unclosed("END_PROPERTY", "PROPERTY", at));
        }
        self.eat(&Tok::Semi);
        if get.is_none() && set.is_none() && prototype {
            // An interface property without GET or SET has both.
            get = Some(accessor(false, Vec::new(), Vec::new()));
            set = Some(accessor(true, Vec::new(), Vec::new()));
        }
        Ok(Property { name, ty, get, set })
    }

    fn interface(&mut self) -> PResult<Interface> {
        let at = self.pos();
        self.bump();
        let name = self.name()?;
        let mut extends = Vec::new();
        if self.eat_kw("EXTENDS") {
            loop {
                extends.push(self.name()?);
                if !self.eat(&Tok::Comma) {
                    break;
                }
            }
        }
        let mut methods = Vec::new();
        let mut properties = Vec::new();
        loop {
            if self.is_kw("METHOD") {
                methods.push(self.method(true)?);
            } else if self.is_kw("PROPERTY") {
                properties.push(self.property(true)?);
            } else if self.eat_kw("END_INTERFACE") {
                self.eat(&Tok::Semi);
                return Ok(Interface {
                    name,
                    extends,
                    methods,
                    properties,
                });
            } else {
                return Err(self.unclosed("END_INTERFACE", "INTERFACE", at));
            }
        }
    }

    fn config(&mut self) -> PResult<Config> {
        let at = self.pos();
        self.bump();
        let name = self.name()?;
        let mut globals = Vec::new();
        let mut resources = Vec::new();
        loop {
            if self.is_kw("VAR_GLOBAL") {
                globals.push(self.var_block()?);
            } else if self.is_kw("RESOURCE") {
                let res_at = self.pos();
                self.bump();
                self.name()?;
                if self.eat_kw("ON") {
                    self.name()?;
                }
                let mut res = Resource {
                    tasks: Vec::new(),
                    programs: Vec::new(),
                };
                self.resource_body(&mut res, &mut globals, ("END_RESOURCE", "RESOURCE", res_at))?;
                resources.push(res);
            } else if self.is_kw("TASK") || self.is_kw("PROGRAM") {
                // A configuration without a RESOURCE: one implicit resource.
                let mut res = Resource {
                    tasks: Vec::new(),
                    programs: Vec::new(),
                };
                self.resource_body(
                    &mut res,
                    &mut globals,
                    ("END_CONFIGURATION", "CONFIGURATION", at),
                )?;
                resources.push(res);
                return Ok(Config {
                    name,
                    globals,
                    resources,
                });
            } else if self.eat_kw("END_CONFIGURATION") {
                return Ok(Config {
                    name,
                    globals,
                    resources,
                });
            } else if self.at_block_end() {
                return Err(self.unclosed("END_CONFIGURATION", "CONFIGURATION", at));
            } else {
                return Err(
                    self.unexpected("VAR_GLOBAL, RESOURCE, TASK, PROGRAM or END_CONFIGURATION")
                );
            }
        }
    }

    /// Tasks, program instances and globals up to `end`, which closes `opener` at `at`.
    fn resource_body(
        &mut self,
        res: &mut Resource,
        globals: &mut Vec<VarBlock>,
        (end, opener, at): (&str, &str, Pos),
    ) -> PResult<()> {
        loop {
            if self.eat_kw(end) {
                return Ok(());
            }
            if self.is_kw("VAR_GLOBAL") {
                globals.push(self.var_block()?);
            } else if self.eat_kw("TASK") {
                let name = self.name()?;
                let mut t = TaskDecl {
                    name,
                    interval: None,
                    priority: None,
                    single: None,
                };
                let open = self.pos();
                self.expect(&Tok::LParen)?;
                loop {
                    let key = self.name()?;
                    self.expect(&Tok::Assign)?;
                    let v = self.expr()?;
                    match key.text.as_str() {
                        "INTERVAL" => t.interval = Some(v),
                        "PRIORITY" => t.priority = Some(v),
                        "SINGLE" => t.single = Some(v),
                        _ => {
                            return Err(CompileError::new(
                                self.file,
                                key.pos,
                                ErrorKind::Syntax,
                                format!(
                                    "unknown task property '{}' (INTERVAL, PRIORITY, SINGLE)",
                                    key.text
                                ),
                            ));
                        }
                    }
                    if !self.eat(&Tok::Comma) {
                        break;
                    }
                }
                self.expect_close(&Tok::RParen, open)?;
                self.expect(&Tok::Semi)?;
                res.tasks.push(t);
            } else if self.is_kw("PROGRAM") {
                let program_at = self.pos();
                self.bump();
                self.eat_kw("RETAIN");
                self.eat_kw("NON_RETAIN");
                let name = self.name()?;
                if !self.is_kw("WITH") && self.peek() != &Tok::Colon {
                    // A PROGRAM POU after a configuration left open.
                    return Err(CompileError::new(
                        self.file,
                        program_at,
                        ErrorKind::Syntax,
                        format!(
                            "{end} expected to close the {opener} at {}:{}, found 'PROGRAM' \
                             (inside it, a program instance is `PROGRAM name WITH task : Type;`)",
                            at.line, at.col
                        ),
                    ));
                }
                let task = if self.eat_kw("WITH") {
                    Some(self.name()?)
                } else {
                    None
                };
                self.expect(&Tok::Colon)?;
                let ty = self.name()?;
                if self.peek() == &Tok::LParen {
                    return Err(self.err("program instance arguments are not supported; use VAR_GLOBAL / VAR_EXTERNAL"));
                }
                self.expect(&Tok::Semi)?;
                res.programs.push(ProgramInst { name, task, ty });
            } else if self.at_block_end() {
                return Err(self.unclosed(end, opener, at));
            } else {
                return Err(self.unexpected(&format!("TASK, PROGRAM, VAR_GLOBAL or {end}")));
            }
        }
    }

    /// Statements up to one of `ends`, inside the construct `opener` that starts at `at`.
    fn stmts(&mut self, ends: &[&str], opener: &str, at: Pos) -> PResult<Vec<Stmt>> {
        let mut out = Vec::new();
        loop {
            if let Tok::Ident(s) = self.peek() {
                if ends.contains(&s.as_str()) {
                    return Ok(out);
                }
            }
            if self.at_block_end() {
                let end = ends
                    .iter()
                    .rev()
                    .find(|e| e.starts_with("END_") || **e == "UNTIL")
                    .copied()
                    .unwrap_or(ends[0]);
                return Err(self.block_end_error(end, opener, at));
            }
            let s = self.stmt()?;
            if !matches!(s, Stmt::Empty) {
                out.push(s);
            }
        }
    }

    fn stmt(&mut self) -> PResult<Stmt> {
        self.stmt_depth += 1;
        if self.stmt_depth > MAX_STMT_DEPTH {
            return Err(self.err(format!("statements nested more than {MAX_STMT_DEPTH} deep")));
        }
        let r = self.stmt_inner();
        self.stmt_depth -= 1;
        r
    }

    fn stmt_inner(&mut self) -> PResult<Stmt> {
        let pos = self.pos();
        if self.eat(&Tok::Semi) {
            return Ok(Stmt::Empty);
        }
        let kw = match self.peek() {
            Tok::Ident(s) => s.clone(),
            Tok::Direct(d) => {
                let text = d.to_string();
                return self.direct_assignment(text, pos);
            }
            _ => return Err(self.unexpected("a statement")),
        };
        let s = match kw.as_str() {
            "IF" => self.if_stmt(pos)?,
            "CASE" => self.case_stmt(pos)?,
            "FOR" => self.for_stmt(pos)?,
            "WHILE" => self.while_stmt(pos)?,
            "REPEAT" => self.repeat_stmt(pos)?,
            "EXIT" => {
                self.bump();
                Stmt::Exit(pos)
            }
            "CONTINUE" => {
                self.bump();
                Stmt::Continue(pos)
            }
            "RETURN" => {
                self.bump();
                Stmt::Return(pos)
            }
            _ => self.assignment_or_call(&kw, pos)?,
        };
        self.end_of_statement(&s, pos)?;
        Ok(s)
    }

    /// `%QX0.4 := ...`: a directly represented variable as the target.
    fn direct_assignment(&mut self, text: String, pos: Pos) -> PResult<Stmt> {
        let root = Name { text, pos };
        self.bump();
        self.expect(&Tok::Assign)?;
        let e = self.expr()?;
        self.expect(&Tok::Semi)?;
        Ok(Stmt::Assign(
            Access {
                root,
                parts: Vec::new(),
            },
            e,
            pos,
        ))
    }

    fn if_stmt(&mut self, pos: Pos) -> PResult<Stmt> {
        self.bump();
        let mut branches = Vec::new();
        let c = self.expr()?;
        self.expect_kw_in("THEN", "IF", pos)?;
        let b = self.stmts(&["ELSIF", "ELSE", "END_IF"], "IF", pos)?;
        branches.push((c, b));
        let mut els = Vec::new();
        loop {
            if self.eat_kw("ELSIF") {
                let c = self.expr()?;
                self.expect_kw_in("THEN", "IF", pos)?;
                let b = self.stmts(&["ELSIF", "ELSE", "END_IF"], "IF", pos)?;
                branches.push((c, b));
            } else if self.eat_kw("ELSE") {
                els = self.stmts(&["END_IF"], "IF", pos)?;
                self.eat_kw("END_IF");
                break;
            } else {
                self.eat_kw("END_IF");
                break;
            }
        }
        Ok(Stmt::If(branches, els, pos))
    }

    fn case_stmt(&mut self, pos: Pos) -> PResult<Stmt> {
        self.bump();
        let sel = self.expr()?;
        self.expect_kw_in("OF", "CASE", pos)?;
        let mut arms = Vec::new();
        let mut els = Vec::new();
        loop {
            if self.eat_kw("ELSE") {
                els = self.stmts(&["END_CASE"], "CASE", pos)?;
                self.eat_kw("END_CASE");
                break;
            }
            if self.at_block_end() && !self.is_kw("END_CASE") {
                return Err(self.unclosed("END_CASE", "CASE", pos));
            }
            if self.eat_kw("END_CASE") {
                break;
            }
            let labels = self.case_labels()?;
            if !self.eat(&Tok::Colon) {
                return Err(self.err(format!(
                    "':' expected after the CASE label (CASE at {}:{}), found {}",
                    pos.line,
                    pos.col,
                    describe(self.peek())
                )));
            }
            let body = self.case_body(pos)?;
            arms.push(CaseArm { labels, body });
        }
        Ok(Stmt::Case(sel, arms, els, pos))
    }

    /// A CASE arm's labels: values and ranges, separated by commas.
    fn case_labels(&mut self) -> PResult<Vec<(Expr, Option<Expr>)>> {
        let mut labels = Vec::new();
        loop {
            let lo = self.expr()?;
            let hi = if self.eat(&Tok::DotDot) {
                Some(self.expr()?)
            } else {
                None
            };
            labels.push((lo, hi));
            if !self.eat(&Tok::Comma) {
                break;
            }
        }
        Ok(labels)
    }

    fn for_stmt(&mut self, pos: Pos) -> PResult<Stmt> {
        self.bump();
        let var = self.name()?;
        self.expect(&Tok::Assign)?;
        let from = self.expr()?;
        self.expect_kw_in("TO", "FOR", pos)?;
        let to = self.expr()?;
        let by = if self.eat_kw("BY") {
            Some(self.expr()?)
        } else {
            None
        };
        self.expect_kw_in("DO", "FOR", pos)?;
        let body = self.stmts(&["END_FOR"], "FOR", pos)?;
        self.eat_kw("END_FOR");
        Ok(Stmt::For {
            var,
            from,
            to,
            by,
            body,
            pos,
        })
    }

    fn while_stmt(&mut self, pos: Pos) -> PResult<Stmt> {
        self.bump();
        let c = self.expr()?;
        self.expect_kw_in("DO", "WHILE", pos)?;
        let body = self.stmts(&["END_WHILE"], "WHILE", pos)?;
        self.eat_kw("END_WHILE");
        Ok(Stmt::While(c, body, pos))
    }

    fn repeat_stmt(&mut self, pos: Pos) -> PResult<Stmt> {
        self.bump();
        let body = self.stmts(&["UNTIL"], "REPEAT", pos)?;
        self.eat_kw("UNTIL");
        let c = self.expr()?;
        self.expect_kw_in("END_REPEAT", "REPEAT", pos)?;
        Ok(Stmt::Repeat(body, c, pos))
    }

    /// A statement that begins with a name `kw` (not a keyword): an assignment or a call.
    fn assignment_or_call(&mut self, kw: &str, pos: Pos) -> PResult<Stmt> {
        if RESERVED.contains(&kw) {
            return Err(self.unexpected("a statement"));
        }
        let target = self.access()?;
        if self.peek() == &Tok::LParen {
            let args = self.args()?;
            Ok(Stmt::Call(target, args, pos))
        } else if self.eat(&Tok::Assign) {
            let e = self.expr()?;
            Ok(Stmt::Assign(target, e, pos))
        } else if self.is_kw("REF") && self.peek_at(1) == &Tok::Eq {
            self.bump();
            self.bump();
            let e = self.expr()?;
            Ok(Stmt::RefAssign(target, e, pos))
        } else {
            if self.peek() == &Tok::Eq {
                return Err(self.err("an assignment is written ':=', not '=' ('=' compares)"));
            }
            Err(self.unexpected("':=', 'REF=' or '(' after the name"))
        }
    }

    /// The `;` after a statement: optional after a compound one (CODESYS and TwinCAT take
    /// END_IF with or without it).
    fn end_of_statement(&mut self, s: &Stmt, pos: Pos) -> PResult<()> {
        let compound = matches!(
            s,
            Stmt::If(..) | Stmt::Case(..) | Stmt::For { .. } | Stmt::While(..) | Stmt::Repeat(..)
        );
        if compound {
            self.eat(&Tok::Semi);
        } else if !matches!(s, Stmt::Empty) && !self.eat(&Tok::Semi) {
            return Err(self.err(format!(
                "';' expected to end the statement at {}:{}, found {}",
                pos.line,
                pos.col,
                describe(self.peek())
            )));
        }
        Ok(())
    }

    /// Statements of one CASE arm: up to the next label (`expr :` / `expr ..`), ELSE or END_CASE.
    fn case_body(&mut self, at: Pos) -> PResult<Vec<Stmt>> {
        let mut out = Vec::new();
        loop {
            if self.is_kw("ELSE") || self.is_kw("END_CASE") {
                return Ok(out);
            }
            if self.at_block_end() {
                return Err(self.unclosed("END_CASE", "CASE", at));
            }
            if self.looks_like_label() {
                return Ok(out);
            }
            let s = self.stmt()?;
            if !matches!(s, Stmt::Empty) {
                out.push(s);
            }
        }
    }

    /// A case label starts with a constant (number, `-number`, enum name, typed literal)
    /// followed by `:`, `,` or `..` at the top level.
    fn looks_like_label(&self) -> bool {
        let mut k = 0;
        if self.peek_at(k) == &Tok::Minus {
            k += 1;
        }
        match self.peek_at(k) {
            Tok::Int(_)
            | Tok::Real(_)
            | Tok::Str(_)
            | Tok::WStr(_)
            | Tok::Time(_)
            | Tok::Moment(..) => {}
            Tok::TypedPrefix(_) => {
                k += 1;
            }
            Tok::Ident(s) if !RESERVED.contains(&s.as_str()) || s == "TRUE" || s == "FALSE" => {
                // `E_Mode.Idle :`
                if self.peek_at(k + 1) == &Tok::Dot && matches!(self.peek_at(k + 2), Tok::Ident(_))
                {
                    k += 2;
                }
            }
            _ => return false,
        }
        k += 1;
        matches!(self.peek_at(k), Tok::Colon | Tok::Comma | Tok::DotDot)
    }

    fn access(&mut self) -> PResult<Access> {
        let root = self.name()?;
        let mut parts = Vec::new();
        loop {
            if self.peek() == &Tok::Dot {
                let pos = self.pos();
                self.bump();
                match self.peek().clone() {
                    Tok::Int(b) => {
                        self.bump();
                        if b > 63 {
                            return Err(CompileError::new(
                                self.file,
                                pos,
                                ErrorKind::Syntax,
                                "bit number must be 0..63",
                            ));
                        }
                        parts.push(Part::Bit(b as u8, pos));
                    }
                    Tok::Real(_) => {
                        return Err(self.err("bit access takes one bit number"));
                    }
                    _ => parts.push(Part::Field(self.name()?)),
                }
            } else if self.peek() == &Tok::Caret {
                parts.push(Part::Deref(self.pos()));
                self.bump();
            } else if self.peek() == &Tok::LBracket {
                let pos = self.pos();
                self.bump();
                let mut idx = vec![self.expr()?];
                while self.eat(&Tok::Comma) {
                    idx.push(self.expr()?);
                }
                self.expect_close(&Tok::RBracket, pos)?;
                parts.push(Part::Index(idx, pos));
            } else {
                return Ok(Access { root, parts });
            }
        }
    }

    fn args(&mut self) -> PResult<Vec<Arg>> {
        let open = self.pos();
        self.expect(&Tok::LParen)?;
        let mut args = Vec::new();
        if self.eat(&Tok::RParen) {
            return Ok(args);
        }
        loop {
            let negated = self.is_kw("NOT")
                && matches!(self.peek_at(1), Tok::Ident(_))
                && self.peek_at(2) == &Tok::Output;
            if negated {
                self.bump();
            }
            if matches!(self.peek(), Tok::Ident(_)) && self.peek_at(1) == &Tok::Assign {
                let n = self.name()?;
                self.bump();
                args.push(Arg::Input(n, self.expr()?));
            } else if matches!(self.peek(), Tok::Ident(_)) && self.peek_at(1) == &Tok::Output {
                let n = self.name()?;
                self.bump();
                let target = if matches!(self.peek(), Tok::Comma | Tok::RParen) {
                    None
                } else {
                    Some(self.access()?)
                };
                args.push(Arg::Output(n, target, negated));
            } else {
                args.push(Arg::Positional(self.expr()?));
            }
            if !self.eat(&Tok::Comma) {
                break;
            }
        }
        self.expect_close(&Tok::RParen, open)?;
        Ok(args)
    }

    pub(crate) fn expr(&mut self) -> PResult<Expr> {
        self.enter()?;
        let r = self.binary(0);
        self.leave();
        r
    }

    fn binop_at(&self, level: u8) -> Option<BinOp> {
        let t = self.peek();
        let kw = |k: &str| matches!(t, Tok::Ident(s) if s == k);
        match level {
            0 if kw("OR") => Some(BinOp::Or),
            1 if kw("XOR") => Some(BinOp::Xor),
            2 if kw("AND") || t == &Tok::Amp => Some(BinOp::And),
            3 => match t {
                Tok::Eq => Some(BinOp::Eq),
                Tok::Ne => Some(BinOp::Ne),
                _ => None,
            },
            4 => match t {
                Tok::Lt => Some(BinOp::Lt),
                Tok::Le => Some(BinOp::Le),
                Tok::Gt => Some(BinOp::Gt),
                Tok::Ge => Some(BinOp::Ge),
                _ => None,
            },
            5 => match t {
                Tok::Plus => Some(BinOp::Add),
                Tok::Minus => Some(BinOp::Sub),
                _ => None,
            },
            6 => match t {
                Tok::Star => Some(BinOp::Mul),
                Tok::Slash => Some(BinOp::Div),
                _ if kw("MOD") => Some(BinOp::Mod),
                _ => None,
            },
            7 if t == &Tok::Power => Some(BinOp::Pow),
            _ => None,
        }
    }

    /// The binary operator at the cursor and its precedence (0 = OR ... 7 = **).
    fn binop(&self) -> Option<(BinOp, u8)> {
        (0..8).find_map(|level| self.binop_at(level).map(|op| (op, level)))
    }

    /// Precedence climbing: one stack frame per nesting level, not per precedence level.
    fn binary(&mut self, min_level: u8) -> PResult<Expr> {
        let mut lhs = self.unary()?;
        let (depth_before, tree_before) = (self.depth, self.tree);
        let result = loop {
            let Some((op, level)) = self.binop().filter(|(_, l)| *l >= min_level) else {
                break Ok(lhs);
            };
            let pos = self.pos();
            self.bump();
            if matches!(op, BinOp::And | BinOp::Or | BinOp::Xor) {
                // Long AND/OR/XOR chains (ladder rungs) become balanced trees: same
                // left-to-right evaluation, logarithmic depth.
                let mut operands = vec![lhs];
                match self.binary(level + 1) {
                    Ok(e) => operands.push(e),
                    Err(e) => break Err(e),
                }
                let mut failed = None;
                while self.binop() == Some((op, level)) {
                    self.bump();
                    match self.binary(level + 1) {
                        Ok(e) => operands.push(e),
                        Err(e) => {
                            failed = Some(e);
                            break;
                        }
                    }
                }
                if let Some(e) = failed {
                    break Err(e);
                }
                lhs = balanced(op, operands, pos);
                continue;
            }
            // Other chains build a tree one level deeper per operator: not nesting, but
            // bounded all the same.
            if let Err(e) = self.deeper_tree() {
                break Err(e);
            }
            match self.binary(level + 1) {
                Ok(rhs) => lhs = Expr::Binary(op, Box::new(lhs), Box::new(rhs), pos),
                Err(e) => break Err(e),
            }
        };
        self.depth = depth_before;
        self.tree = tree_before;
        result
    }

    fn unary(&mut self) -> PResult<Expr> {
        let pos = self.pos();
        let op = if self.peek() == &Tok::Minus {
            Some(UnOp::Neg)
        } else if self.peek() == &Tok::Plus {
            Some(UnOp::Plus)
        } else if self.is_kw("NOT") {
            Some(UnOp::Not)
        } else {
            None
        };
        match op {
            Some(op) => {
                self.bump();
                self.enter()?;
                let e = self.unary();
                self.leave();
                let e = e?;
                // Fold a minus into a numeric literal so INT#-32768 style bounds work.
                if op == UnOp::Neg {
                    if let Expr::Lit(Literal::Real(v), p) = e {
                        return Ok(Expr::Lit(Literal::Real(-v), p));
                    }
                    if let Expr::Lit(Literal::Time(v), p) = e {
                        return Ok(Expr::Lit(Literal::Time(-v), p));
                    }
                }
                Ok(Expr::Unary(op, Box::new(e), pos))
            }
            None => self.primary(),
        }
    }

    fn primary(&mut self) -> PResult<Expr> {
        let pos = self.pos();
        match self.peek().clone() {
            Tok::Int(v) => {
                self.bump();
                Ok(Expr::Lit(Literal::Int(v), pos))
            }
            Tok::Real(v) => {
                self.bump();
                Ok(Expr::Lit(Literal::Real(v), pos))
            }
            Tok::Time(v) => {
                self.bump();
                Ok(Expr::Lit(Literal::Time(v), pos))
            }
            Tok::Moment(k, v) => {
                self.bump();
                Ok(Expr::Lit(Literal::Moment(k, v), pos))
            }
            Tok::Str(s) => {
                self.bump();
                Ok(Expr::Lit(Literal::Str(s), pos))
            }
            Tok::WStr(s) => {
                self.bump();
                Ok(Expr::Lit(Literal::WStr(s), pos))
            }
            Tok::Direct(d) => {
                self.bump();
                Ok(Expr::Direct(d, pos))
            }
            Tok::TypedPrefix(p) => {
                self.bump();
                let name = Name { text: p, pos };
                if matches!(self.peek(), Tok::Ident(s) if s != "TRUE" && s != "FALSE") {
                    let v = self.name()?;
                    return Ok(Expr::EnumValue(name, v));
                }
                let neg = self.eat(&Tok::Minus);
                let inner = self.primary()?;
                let inner = if neg {
                    Expr::Unary(UnOp::Neg, Box::new(inner), pos)
                } else {
                    inner
                };
                Ok(Expr::Typed(name, Box::new(inner)))
            }
            Tok::LParen => {
                let open = self.pos();
                self.bump();
                let e = self.expr()?;
                if !self.eat(&Tok::RParen) {
                    return Err(self.unclosed("')'", "'('", open));
                }
                Ok(e)
            }
            // Operators in function form: AND(a, b, c), OR(...), XOR(...), MOD(a, b).
            Tok::Ident(s)
                if matches!(s.as_str(), "AND" | "OR" | "XOR" | "MOD")
                    && self.peek_at(1) == &Tok::LParen =>
            {
                self.bump();
                let args = self.args()?;
                Ok(Expr::Call(Name { text: s, pos }, args, pos))
            }
            Tok::Ident(s) if s == "TRUE" || s == "FALSE" => {
                self.bump();
                Ok(Expr::Lit(Literal::Bool(s == "TRUE"), pos))
            }
            Tok::Ident(_) => {
                let a = self.access()?;
                if self.peek() == &Tok::LParen {
                    let mut a = a;
                    return match a.parts.pop() {
                        None => Ok(Expr::Call(a.root, self.args()?, pos)),
                        Some(Part::Field(m)) => {
                            let args = self.args()?;
                            Ok(Expr::MethodCall(Box::new((a, m)), args, pos))
                        }
                        Some(_) => Err(self
                            .err("only functions and methods can be called inside an expression")),
                    };
                }
                Ok(Expr::Var(a))
            }
            _ => Err(self.unexpected("an expression")),
        }
    }
}

/// `op` over `operands` as a balanced tree, operands kept in order.
fn balanced(op: BinOp, mut operands: Vec<Expr>, pos: Pos) -> Expr {
    if operands.len() == 1 {
        if let Some(e) = operands.pop() {
            return e;
        }
    }
    // Called with two or more operands: both halves are non-empty.
    let right = operands.split_off(operands.len() / 2);
    Expr::Binary(
        op,
        Box::new(balanced(op, operands, pos)),
        Box::new(balanced(op, right, pos)),
        pos,
    )
}
