//! The binary's handlers each make exactly one call into an igi library crate (issue 31: "the
//! binary parses, makes one library call, and reports").
//!
//! The check parses the binary's sources with `syn` (no regular expressions) and follows a
//! strict convention:
//!
//! * **Handlers.** `src/main.rs` dispatches each subcommand to `cmd::MODULE::FUNCTION`. A
//!   function whose body is one `match` (a subcommand with sub-subcommands) has one handler per
//!   arm, and an arm that only calls a local function hands over to it (expanded the same way);
//!   any other function is itself one handler. A `match`'s scrutinee counts toward every arm.
//! * **What a handler runs.** Its body, the closures in it, the arguments of the macros in it
//!   (parsed as expressions; `json!` by its JSON grammar; a macro whose arguments are neither is
//!   refused, so nothing hides there), and, transitively, the binary's own functions and
//!   methods it calls (`f`, `super::f`, `crate::report::f`, `x.method()` of an `impl` in
//!   `src/`).
//! * **Library calls.** A path that resolves to an `igi_*` crate, written out or through the
//!   file's `use` declarations (a glob `use igi_x::*` is refused), naming a function (its last
//!   segment starts with a lower-case letter), called or passed as a value; constructors
//!   (`Type(..)`, `Variant(..)`: upper-case last segment) and `Type::default()` build the
//!   request and are not calls into the library. A method call `x.name(..)` whose name is a
//!   public method with a `self` receiver of an inherent `impl` in `crates/*/src` (and not the
//!   binary's own), except the standard accessors of [`STD_ACCESSORS`], which igi's types share
//!   with the standard library and which only read values for the report.
//!
//! Each handler must make exactly one library call; `library_calls_are_counted_exactly`
//! checks the checker on small sources (two calls fail, constructors do not count, helpers and
//! macro arguments are followed).

use std::collections::{BTreeMap, BTreeSet};
use syn::parse::{ParseStream, Parser};
use syn::punctuated::Punctuated;
use syn::visit::Visit;
use syn::{Expr, Token};

/// Method names igi's types share with the standard library's collections, options and
/// iterators (`Vec::len`, `Option::as_ref`, `Iterator::count`, `Result::ok`, ...); a handler reading them is
/// reporting, not calling into the library. Each is the name of some library method (checked
/// by the test), so the list holds no name the rule does not need.
pub const STD_ACCESSORS: &[&str] = &[
    "as_ref", "contains", "count", "get", "is_empty", "len", "ok",
];

/// One source file of the binary: its module name (`main`, `report`, `cmd`, or a subcommand's
/// module) and its parsed items.
pub struct BinaryFile {
    pub module: String,
    pub file: syn::File,
}

/// A handler and the library calls it makes (as written, resolved).
#[derive(Debug)]
pub struct Handler {
    pub name: String,
    pub calls: Vec<String>,
}

/// The handlers of the binary made of `files` (`main` dispatching into `cmd::MODULE::FN`),
/// each with its library calls; `methods`: the libraries' public method names.
pub fn handlers(files: &[BinaryFile], methods: &BTreeSet<String>) -> Result<Vec<Handler>, String> {
    let bin = Binary::new(files, methods)?;
    let main = bin
        .function("main", "main")
        .ok_or("src/main.rs has no fn main")?;
    let mut entries = Vec::new();
    collect_entries(&main.block, &mut entries);
    if entries.is_empty() {
        return Err("fn main dispatches to no cmd::MODULE::FUNCTION".into());
    }
    let mut out = Vec::new();
    for (module, f) in entries {
        bin.expand(&module, &f, &format!("{module}::{f}"), &mut out)?;
    }
    Ok(out)
}

/// The binary's functions and methods by module, the imports of each module, and the
/// libraries' method names.
struct Binary<'a> {
    fns: BTreeMap<(String, String), &'a syn::ItemFn>,
    methods: BTreeMap<String, Vec<(String, &'a syn::ImplItemFn)>>,
    imports: BTreeMap<String, BTreeMap<String, Vec<String>>>,
    library_methods: &'a BTreeSet<String>,
}

impl<'a> Binary<'a> {
    fn new(files: &'a [BinaryFile], library_methods: &'a BTreeSet<String>) -> Result<Self, String> {
        let mut b = Binary {
            fns: BTreeMap::new(),
            methods: BTreeMap::new(),
            imports: BTreeMap::new(),
            library_methods,
        };
        for f in files {
            let imports = b.imports.entry(f.module.clone()).or_default();
            for item in &f.file.items {
                match item {
                    syn::Item::Fn(func) => {
                        b.fns
                            .insert((f.module.clone(), func.sig.ident.to_string()), func);
                    }
                    syn::Item::Impl(imp) => {
                        for it in &imp.items {
                            if let syn::ImplItem::Fn(m) = it {
                                let name = m.sig.ident.to_string();
                                b.methods
                                    .entry(name)
                                    .or_default()
                                    .push((f.module.clone(), m));
                            }
                        }
                    }
                    syn::Item::Use(u) => use_tree(&u.tree, &mut Vec::new(), imports)
                        .map_err(|e| format!("{}: {e}", f.module))?,
                    _ => {}
                }
            }
        }
        Ok(b)
    }

    fn function(&self, module: &str, name: &str) -> Option<&'a syn::ItemFn> {
        self.fns
            .get(&(module.to_string(), name.to_string()))
            .copied()
    }

    /// The handlers of function `module::name`: one per arm when its body is one `match`.
    fn expand(
        &self,
        module: &str,
        name: &str,
        label: &str,
        out: &mut Vec<Handler>,
    ) -> Result<(), String> {
        let f = self
            .function(module, name)
            .ok_or(format!("no fn {name} in src/cmd/{module}.rs"))?;
        let Some(m) = sole_match(&f.block) else {
            let calls = self.calls_in(module, |v| v.visit_block(&f.block))?;
            out.push(Handler {
                name: label.to_string(),
                calls,
            });
            return Ok(());
        };
        let scrutinee = self.calls_in(module, |v| v.visit_expr(&m.expr))?;
        for arm in &m.arms {
            let pat = quote_pat(&arm.pat);
            match local_call(&arm.body).filter(|g| self.function(module, g).is_some()) {
                Some(g) if sole_match(&self.function(module, &g).unwrap().block).is_some() => {
                    self.expand(module, &g, &format!("{label} {pat} -> {g}"), out)?
                }
                _ => {
                    let mut calls = scrutinee.clone();
                    calls.extend(self.calls_in(module, |v| v.visit_expr(&arm.body))?);
                    out.push(Handler {
                        name: format!("{label} {pat}"),
                        calls,
                    });
                }
            }
        }
        Ok(())
    }

    /// The library calls of what `visit` walks in `module`, following the binary's own
    /// functions and methods.
    fn calls_in(
        &self,
        module: &str,
        visit: impl FnOnce(&mut Calls),
    ) -> Result<Vec<String>, String> {
        let mut v = Calls {
            bin: self,
            module: module.to_string(),
            calls: Vec::new(),
            seen: BTreeSet::new(),
            error: None,
        };
        visit(&mut v);
        match v.error {
            Some(e) => Err(e),
            None => Ok(v.calls),
        }
    }
}

/// The `use` declarations of a file, as alias -> full path.
fn use_tree(
    tree: &syn::UseTree,
    prefix: &mut Vec<String>,
    out: &mut BTreeMap<String, Vec<String>>,
) -> Result<(), String> {
    match tree {
        syn::UseTree::Path(p) => {
            prefix.push(p.ident.to_string());
            use_tree(&p.tree, prefix, out)?;
            prefix.pop();
        }
        syn::UseTree::Name(n) => {
            let name = n.ident.to_string();
            let mut full = prefix.clone();
            if name != "self" {
                full.push(name.clone());
            }
            out.insert(full.last().cloned().unwrap_or(name), full);
        }
        syn::UseTree::Rename(r) => {
            let mut full = prefix.clone();
            full.push(r.ident.to_string());
            out.insert(r.rename.to_string(), full);
        }
        syn::UseTree::Glob(_) if prefix.first().is_some_and(|s| s.starts_with("igi_")) => {
            return Err(format!(
                "glob import `{}::*` hides which library is called",
                prefix.join("::")
            ));
        }
        syn::UseTree::Glob(_) => {}
        syn::UseTree::Group(g) => {
            for t in &g.items {
                use_tree(t, prefix, out)?;
            }
        }
    }
    Ok(())
}

/// The `match` that is a block's only statement or its value, if any.
fn sole_match(block: &syn::Block) -> Option<&syn::ExprMatch> {
    match block.stmts.as_slice() {
        [syn::Stmt::Expr(Expr::Match(m), _)] => Some(m),
        _ => None,
    }
}

/// The local function an arm only calls (`f(..)`, possibly in a block of one expression).
fn local_call(e: &Expr) -> Option<String> {
    match e {
        Expr::Call(c) => match &*c.func {
            Expr::Path(p) if p.path.segments.len() == 1 => {
                Some(p.path.segments[0].ident.to_string())
            }
            _ => None,
        },
        Expr::Block(b) => match b.block.stmts.as_slice() {
            [syn::Stmt::Expr(e, None)] => local_call(e),
            _ => None,
        },
        _ => None,
    }
}

fn quote_pat(p: &syn::Pat) -> String {
    match p {
        syn::Pat::TupleStruct(t) => path_text(&t.path),
        syn::Pat::Path(p) => path_text(&p.path),
        syn::Pat::Ident(i) => i.ident.to_string(),
        _ => "_".into(),
    }
}

fn path_text(p: &syn::Path) -> String {
    let s: Vec<String> = p.segments.iter().map(|s| s.ident.to_string()).collect();
    s.join("::")
}

/// Walks a handler, collecting its library calls.
struct Calls<'b, 'a> {
    bin: &'b Binary<'a>,
    module: String,
    calls: Vec<String>,
    /// The binary's functions already followed (a helper called twice counts twice; recursion
    /// stops).
    seen: BTreeSet<(String, String)>,
    error: Option<String>,
}

impl Calls<'_, '_> {
    /// A path in an expression: a library function (counted), the binary's own function
    /// (followed), or anything else.
    fn path(&mut self, p: &syn::Path) {
        let segs: Vec<String> = p.segments.iter().map(|s| s.ident.to_string()).collect();
        let imports = &self.bin.imports[&self.module];
        let full = match imports.get(&segs[0]) {
            Some(f) => f.iter().cloned().chain(segs[1..].iter().cloned()).collect(),
            None => segs.clone(),
        };
        let last = full.last().unwrap();
        let function = last.starts_with(|c: char| c.is_ascii_lowercase()) && last != "default";
        if full[0].starts_with("igi_") {
            if function {
                self.calls.push(full.join("::"));
            }
            return;
        }
        let target = match full
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>()
            .as_slice()
        {
            [f] => Some((self.module.clone(), f.to_string())),
            ["super", f] | ["crate", "cmd", f] => Some(("cmd".into(), f.to_string())),
            ["crate", "report", f] => Some(("report".into(), f.to_string())),
            ["crate", "cmd", m, f] | ["super", m, f] => Some((m.to_string(), f.to_string())),
            ["Self", m] => return self.method(m),
            _ => None,
        };
        if let Some((m, f)) = target {
            if let Some(func) = self.bin.function(&m, &f) {
                self.follow(m, f, |v| v.visit_block(&func.block));
            } else if segs.len() == 2
                && self.bin.methods.contains_key(&segs[1])
                && is_type(&segs[0])
            {
                self.method(&segs[1]);
            }
        } else if segs.len() == 2 && is_type(&segs[0]) && self.bin.methods.contains_key(&segs[1]) {
            self.method(&segs[1]);
        }
    }

    /// A method call: the binary's own method (followed), or a library method (counted).
    fn method(&mut self, name: &str) {
        let Some(defs) = self.bin.methods.get(name) else {
            if self.bin.library_methods.contains(name) && !STD_ACCESSORS.contains(&name) {
                self.calls.push(format!(".{name}()"));
            }
            return;
        };
        let here: Vec<_> = defs.iter().filter(|(m, _)| *m == self.module).collect();
        let chosen = match (here.as_slice(), defs.as_slice()) {
            ([one], _) => *one,
            ([], [one]) => one,
            _ => {
                self.error = Some(format!(
                    "method `{name}` of the binary is ambiguous from {}",
                    self.module
                ));
                return;
            }
        };
        let (m, f) = (chosen.0.clone(), chosen.1);
        self.follow(m, name.to_string(), |v| v.visit_block(&f.block));
    }

    fn follow(&mut self, module: String, name: String, walk: impl FnOnce(&mut Self)) {
        let key = (module.clone(), name);
        if !self.seen.insert(key.clone()) {
            return;
        }
        let saved = std::mem::replace(&mut self.module, module);
        walk(self);
        self.module = saved;
        self.seen.remove(&key);
    }

    /// A macro's arguments as expressions (`json!` by its grammar); others are refused.
    fn mac(&mut self, m: &syn::Macro) {
        let name = m
            .path
            .segments
            .last()
            .map(|s| s.ident.to_string())
            .unwrap_or_default();
        let exprs = if name == "json" {
            (|input: ParseStream| json_exprs(input)).parse2(m.tokens.clone())
        } else {
            Punctuated::<Expr, Token![,]>::parse_terminated
                .parse2(m.tokens.clone())
                .map(|p| p.into_iter().collect())
        };
        match exprs {
            Ok(es) => es.iter().for_each(|e| self.visit_expr(e)),
            Err(e) => {
                self.error = Some(format!(
                    "{}: cannot read the arguments of `{name}!`: {e}",
                    self.module
                ))
            }
        }
    }
}

fn is_type(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_uppercase())
}

/// The expressions in a `json!` value: objects `{ "key": value, .. }`, arrays, expressions.
fn json_exprs(input: ParseStream) -> syn::Result<Vec<Expr>> {
    let mut out = Vec::new();
    if input.peek(syn::token::Brace) {
        let content;
        syn::braced!(content in input);
        while !content.is_empty() {
            content.parse::<syn::Lit>()?;
            content.parse::<Token![:]>()?;
            out.extend(json_exprs(&content)?);
            if !content.is_empty() {
                content.parse::<Token![,]>()?;
            }
        }
    } else if input.peek(syn::token::Bracket) {
        let content;
        syn::bracketed!(content in input);
        while !content.is_empty() {
            out.extend(json_exprs(&content)?);
            if !content.is_empty() {
                content.parse::<Token![,]>()?;
            }
        }
    } else {
        out.push(input.parse::<Expr>()?);
    }
    Ok(out)
}

impl<'ast> Visit<'ast> for Calls<'_, '_> {
    fn visit_expr_call(&mut self, c: &'ast syn::ExprCall) {
        match &*c.func {
            Expr::Path(p) => self.path(&p.path),
            f => self.visit_expr(f),
        }
        c.args.iter().for_each(|a| self.visit_expr(a));
    }

    fn visit_expr_path(&mut self, p: &'ast syn::ExprPath) {
        // a function passed as a value, e.g. `.map(igi_geometry::read_mesh)`
        self.path(&p.path);
    }

    fn visit_expr_method_call(&mut self, m: &'ast syn::ExprMethodCall) {
        self.visit_expr(&m.receiver);
        self.method(&m.method.to_string());
        m.args.iter().for_each(|a| self.visit_expr(a));
    }

    fn visit_macro(&mut self, m: &'ast syn::Macro) {
        self.mac(m);
    }
}

/// `cmd::MODULE::FUNCTION` calls in `fn main`.
fn collect_entries(block: &syn::Block, out: &mut Vec<(String, String)>) {
    struct Entries<'o>(&'o mut Vec<(String, String)>);
    impl<'ast> Visit<'ast> for Entries<'_> {
        fn visit_expr_call(&mut self, c: &'ast syn::ExprCall) {
            if let Expr::Path(p) = &*c.func {
                let s: Vec<String> = p
                    .path
                    .segments
                    .iter()
                    .map(|s| s.ident.to_string())
                    .collect();
                if let [c, m, f] = s.as_slice() {
                    if c == "cmd" {
                        self.0.push((m.clone(), f.clone()));
                    }
                }
            }
            syn::visit::visit_expr_call(self, c);
        }
    }
    Entries(out).visit_block(block);
}

/// The public methods with a `self` receiver of the inherent `impl`s in `file`.
pub fn public_methods(file: &syn::File, out: &mut BTreeSet<String>) {
    struct Methods<'o>(&'o mut BTreeSet<String>);
    impl<'ast> Visit<'ast> for Methods<'_> {
        fn visit_item_impl(&mut self, i: &'ast syn::ItemImpl) {
            if i.trait_.is_none() {
                for it in &i.items {
                    if let syn::ImplItem::Fn(f) = it {
                        let public = matches!(f.vis, syn::Visibility::Public(_));
                        if public && f.sig.receiver().is_some() {
                            self.0.insert(f.sig.ident.to_string());
                        }
                    }
                }
            }
            syn::visit::visit_item_impl(self, i);
        }
    }
    Methods(out).visit_file(file);
}
