//! The file-level import graph of a crate: which source file names items of which other file
//! of the same crate (`use crate::...`, `use super::...`, `crate::x::f()` in code, a child
//! module's name), and the circles in it. Comments and string literals are not read, so an
//! intra-doc link is not an import. Read from the source text alone: the crate's module tree
//! is followed from its root through `mod x;` declarations (with `#[path]`), inline modules
//! (`mod tests { use super::*; }`) count as part of their file.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A token of Rust source, as far as imports need one.
#[derive(Clone, Debug, PartialEq)]
enum Token {
    Ident(String),
    /// `::`
    PathSep,
    Str(String),
    Punct(char),
}

/// The tokens of `src`, comments and lifetimes dropped, literals kept as strings.
fn tokens(src: &str) -> Vec<Token> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    let ident_start = |ch: char| ch.is_alphabetic() || ch == '_';
    let ident_char = |ch: char| ch.is_alphanumeric() || ch == '_';
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied();
        if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && next == Some('*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if let Some((len, text)) = raw_string(&c[i..]) {
            out.push(Token::Str(text));
            i += len;
        } else if ch == '"' || (ch == 'b' && next == Some('"')) {
            i += if ch == 'b' { 2 } else { 1 };
            let mut text = String::new();
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    i += 1;
                }
                if let Some(&x) = c.get(i) {
                    text.push(x);
                }
                i += 1;
            }
            out.push(Token::Str(text));
            i += 1;
        } else if ch == '\'' || (ch == 'b' && next == Some('\'')) {
            let start = if ch == 'b' { i + 1 } else { i };
            // A char literal ('a', '\n', '\u{..}') or a lifetime ('a, 'static).
            if c.get(start + 1) == Some(&'\\') {
                i = start + 2;
                while i < c.len() && c[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if c.get(start + 2) == Some(&'\'') {
                i = start + 3;
            } else {
                i = start + 1;
                while i < c.len() && ident_char(c[i]) {
                    i += 1;
                }
            }
        } else if ident_start(ch) {
            let mut word = String::new();
            if ch == 'r' && next == Some('#') && c.get(i + 2).is_some_and(|&x| ident_start(x)) {
                i += 2;
            }
            while i < c.len() && ident_char(c[i]) {
                word.push(c[i]);
                i += 1;
            }
            out.push(Token::Ident(word));
        } else if ch.is_ascii_digit() {
            while i < c.len()
                && (ident_char(c[i])
                    || c[i] == '.' && c.get(i + 1).is_some_and(char::is_ascii_digit))
            {
                i += 1;
            }
        } else if ch == ':' && next == Some(':') {
            out.push(Token::PathSep);
            i += 2;
        } else {
            out.push(Token::Punct(ch));
            i += 1;
        }
    }
    out
}

/// A raw (byte) string literal at the start of `c`: its length in chars and its text.
fn raw_string(c: &[char]) -> Option<(usize, String)> {
    let mut i = match c {
        ['r', '#' | '"', ..] => 1,
        ['b', 'r', '#' | '"', ..] => 2,
        _ => return None,
    };
    let mut hashes = 0;
    while c.get(i) == Some(&'#') {
        hashes += 1;
        i += 1;
    }
    if c.get(i) != Some(&'"') {
        return None;
    }
    i += 1;
    let start = i;
    while i < c.len() {
        if c[i] == '"' && (1..=hashes).all(|k| c.get(i + k) == Some(&'#')) {
            return Some((i + 1 + hashes, c[start..i].iter().collect()));
        }
        i += 1;
    }
    Some((c.len(), c[start..].iter().collect()))
}

/// What one file says about modules: the file modules it declares and the paths it names.
#[derive(Default)]
struct FileFacts {
    /// `mod x;` declarations: the inline modules around it, the name, a `#[path]` if given.
    declared: Vec<(Vec<String>, String, Option<String>)>,
    /// Paths that may name the crate's own modules: the inline modules around the place, and
    /// the path's segments (`crate`, `super`, `self` kept; a use tree expanded).
    paths: Vec<(Vec<String>, Vec<String>)>,
}

fn ident(t: Option<&Token>) -> Option<&str> {
    match t {
        Some(Token::Ident(s)) => Some(s),
        _ => None,
    }
}

/// Expand the use tree starting at `t[*i]` (after `use`) into its paths, with `prefix` before
/// each; `*i` is left after the tree.
fn use_tree(t: &[Token], i: &mut usize, prefix: &[String], out: &mut Vec<Vec<String>>) {
    let mut path = prefix.to_vec();
    loop {
        match t.get(*i) {
            Some(Token::PathSep) => *i += 1,
            Some(Token::Ident(s)) if s == "as" => {
                *i += 2;
                out.push(path);
                return;
            }
            Some(Token::Ident(s)) => {
                path.push(s.clone());
                *i += 1;
            }
            Some(Token::Punct('*')) => {
                *i += 1;
                out.push(path);
                return;
            }
            Some(Token::Punct('{')) => {
                *i += 1;
                loop {
                    match t.get(*i) {
                        Some(Token::Punct('}')) => {
                            *i += 1;
                            return;
                        }
                        Some(Token::Punct(',')) => *i += 1,
                        None => return,
                        _ => use_tree(t, i, &path, out),
                    }
                }
            }
            _ => {
                out.push(path);
                return;
            }
        }
    }
}

/// The module facts of one file's source.
fn facts(src: &str) -> FileFacts {
    let t = tokens(src);
    let mut f = FileFacts::default();
    // Inline modules open around the current token, with the brace depth they opened at.
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut path_attr: Option<String> = None;
    let mut i = 0;
    let here = |inline: &[(String, usize)]| inline.iter().map(|(n, _)| n.clone()).collect();
    while i < t.len() {
        match &t[i] {
            Token::Punct('#')
                if t.get(i + 1) == Some(&Token::Punct('['))
                    && ident(t.get(i + 2)) == Some("path")
                    && t.get(i + 3) == Some(&Token::Punct('=')) =>
            {
                if let Some(Token::Str(p)) = t.get(i + 4) {
                    path_attr = Some(p.clone());
                }
                i += 5;
            }
            Token::Punct('{') => {
                depth += 1;
                i += 1;
            }
            Token::Punct('}') => {
                depth = depth.saturating_sub(1);
                if inline.last().is_some_and(|(_, d)| *d == depth) {
                    inline.pop();
                }
                i += 1;
            }
            Token::Ident(w) if w == "mod" => match (ident(t.get(i + 1)), t.get(i + 2)) {
                (Some(name), Some(Token::Punct(';'))) => {
                    f.declared
                        .push((here(&inline), name.to_string(), path_attr.take()));
                    i += 3;
                }
                (Some(name), Some(Token::Punct('{'))) => {
                    inline.push((name.to_string(), depth));
                    depth += 1;
                    path_attr = None;
                    i += 3;
                }
                _ => i += 1,
            },
            Token::Ident(w) if w == "use" => {
                i += 1;
                let mut paths = Vec::new();
                use_tree(&t, &mut i, &[], &mut paths);
                for p in paths {
                    f.paths.push((here(&inline), p));
                }
            }
            Token::Ident(w)
                if t.get(i + 1) == Some(&Token::PathSep)
                    && (i == 0 || t[i - 1] != Token::PathSep) =>
            {
                let mut p = vec![w.clone()];
                let mut j = i + 1;
                while t.get(j) == Some(&Token::PathSep) {
                    match ident(t.get(j + 1)) {
                        Some(s) => p.push(s.to_string()),
                        None => break,
                    }
                    j += 2;
                }
                f.paths.push((here(&inline), p));
                i = j;
            }
            _ => i += 1,
        }
    }
    f
}

/// One crate's import graph: its files (relative to `base`) and, per file, the files it
/// imports from with the names taken.
pub struct Graph {
    pub files: Vec<String>,
    pub edges: BTreeMap<String, BTreeMap<String, BTreeSet<String>>>,
}

/// The import graph of the crate whose root file is `root`, file names relative to `base`.
pub fn graph(root: &Path, base: &Path) -> Result<Graph, String> {
    // Module path -> file, and the facts of each file, following `mod x;` from the root.
    let mut modules: BTreeMap<Vec<String>, PathBuf> = BTreeMap::new();
    let mut file_facts: BTreeMap<PathBuf, (Vec<String>, FileFacts)> = BTreeMap::new();
    let mut todo = vec![(Vec::<String>::new(), root.to_path_buf(), true)];
    while let Some((module, file, owns_dir)) = todo.pop() {
        let src = std::fs::read_to_string(&file)
            .map_err(|e| format!("reading {}: {e}", file.display()))?;
        let ff = facts(&src);
        let dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
        // A file that is not a root or a mod.rs keeps its children in a folder of its name.
        let own = if owns_dir {
            dir.clone()
        } else {
            dir.join(file.file_stem().unwrap_or_default())
        };
        for (inline, name, attr) in &ff.declared {
            let mut child = module.clone();
            child.extend(inline.iter().cloned());
            child.push(name.clone());
            let (path, owns) = match attr {
                Some(p) if inline.is_empty() => (dir.join(p), true),
                Some(p) => (
                    inline.iter().fold(own.clone(), |d, m| d.join(m)).join(p),
                    true,
                ),
                None => {
                    let d = inline.iter().fold(own.clone(), |d, m| d.join(m));
                    let flat = d.join(format!("{name}.rs"));
                    if flat.exists() {
                        (flat, false)
                    } else {
                        (d.join(name).join("mod.rs"), true)
                    }
                }
            };
            modules.insert(child.clone(), path.clone());
            todo.push((child, path, owns));
        }
        modules.insert(module.clone(), file.clone());
        file_facts.insert(file, (module, ff));
    }
    let rel = |p: &Path| p.strip_prefix(base).unwrap_or(p).display().to_string();
    let mut edges: BTreeMap<String, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (file, (module, ff)) in &file_facts {
        for (inline, p) in &ff.paths {
            let mut here = module.clone();
            here.extend(inline.iter().cloned());
            let Some(full) = absolute(&here, p, &modules) else {
                continue;
            };
            // The longest prefix of the path that is a file module is the file it names.
            let Some((target_mod, target)) = (0..=full.len())
                .rev()
                .find_map(|n| modules.get_key_value(&full[..n]))
            else {
                continue;
            };
            if target == file {
                continue;
            }
            let name = full
                .get(target_mod.len())
                .cloned()
                .unwrap_or_else(|| "*".into());
            edges
                .entry(rel(file))
                .or_default()
                .entry(rel(target))
                .or_default()
                .insert(name);
        }
    }
    Ok(Graph {
        files: file_facts.keys().map(|f| rel(f)).collect(),
        edges,
    })
}

/// Path `p`, named in module `here`, from the crate root; `None` when it starts outside the
/// crate (another crate, `std`, a local item).
fn absolute(
    here: &[String],
    p: &[String],
    modules: &BTreeMap<Vec<String>, PathBuf>,
) -> Option<Vec<String>> {
    let first = p.first()?;
    let mut base: Vec<String> = here.to_vec();
    let mut rest = p;
    if first == "crate" {
        base.clear();
        rest = &p[1..];
    } else if first == "self" {
        rest = &p[1..];
    } else if first == "super" {
        while rest.first().is_some_and(|s| s == "super") {
            base.pop()?;
            rest = &rest[1..];
        }
    } else {
        // A child module of `here`, named without `self::`.
        let mut child = here.to_vec();
        child.push(first.clone());
        if !modules.contains_key(&child) {
            return None;
        }
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// The circles of `g`: each set of two or more files that reach one another through imports
/// (strongly connected components, Tarjan), files sorted.
pub fn circles(g: &Graph) -> Vec<Vec<String>> {
    struct Walk<'a> {
        g: &'a Graph,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(w: &mut Walk<'a>, v: &'a str) {
        let n = w.index.len();
        w.index.insert(v, n);
        w.low.insert(v, n);
        w.stack.push(v);
        w.on_stack.insert(v);
        let g = w.g;
        for u in g.edges.get(v).into_iter().flat_map(|m| m.keys()) {
            let u = u.as_str();
            if !w.index.contains_key(u) {
                visit(w, u);
                let lu = w.low[u];
                let lv = w.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lu);
            } else if w.on_stack.contains(u) {
                let iu = w.index[u];
                let lv = w.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iu);
            }
        }
        if w.low[v] == w.index[v] {
            let mut comp = Vec::new();
            while let Some(x) = w.stack.pop() {
                w.on_stack.remove(x);
                comp.push(x.to_string());
                if x == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                w.out.push(comp);
            }
        }
    }
    let mut w = Walk {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for f in &g.files {
        if !w.index.contains_key(f.as_str()) {
            visit(&mut w, f);
        }
    }
    w.out.sort();
    w.out
}

/// A circle in words: each of its files with the files of the circle it imports from and the
/// names it takes.
pub fn describe(g: &Graph, circle: &[String]) -> String {
    let mut text = String::new();
    for a in circle {
        for (b, names) in g.edges.get(a).into_iter().flatten() {
            if circle.contains(b) {
                let names: Vec<&str> = names.iter().map(String::as_str).collect();
                text.push_str(&format!("\n    {a} -> {b}: {}", names.join(", ")));
            }
        }
    }
    text
}
