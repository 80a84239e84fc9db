//! Every public item of the library (a `pub fn`, `const`, `static`, `struct`, `enum`, `type` or
//! `trait` outside the front-end in src/cli) has a caller: its name is written somewhere else in
//! the sources of src/, python/, tests/, benches/ or fuzz/, in code or in a doctest (a mention
//! in prose does not count). An item nobody calls is removed or used.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries {
        let p = e.unwrap().path();
        if p.is_dir() {
            if !matches!(
                p.file_name().unwrap().to_str(),
                Some("target" | ".venv" | "__pycache__")
            ) {
                files(&p, out);
            }
        } else if p
            .extension()
            .is_some_and(|x| x == "rs" || x == "py" || x == "pyi")
        {
            out.push(p);
        }
    }
}

/// The lines of a source file that are code: not comments, except a doctest's lines (between
/// ``` fences of `///` or `//!` comments).
fn code_lines(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for (i, l) in text.lines().enumerate() {
        let t = l.trim_start();
        let doc = t.strip_prefix("///").or_else(|| t.strip_prefix("//!"));
        if let Some(d) = doc {
            if d.trim_start().starts_with("```") {
                fenced = !fenced;
            } else if fenced {
                out.push((i + 1, d));
            }
        } else if !t.starts_with("//") && !t.starts_with('#') || t.starts_with("#[") {
            out.push((i + 1, l));
        }
    }
    out
}

/// The name a line declares public (`pub fn name`, `pub const NAME`, ...), if it does.
fn declared(line: &str) -> Option<&str> {
    let mut rest = line.trim_start().strip_prefix("pub ")?;
    for q in ["const ", "unsafe "] {
        if let Some(r) = rest.strip_prefix(q) {
            if r.starts_with("fn ") {
                rest = r;
            }
        }
    }
    let kinds = [
        "fn ", "const ", "static ", "struct ", "enum ", "type ", "trait ",
    ];
    let r = kinds.iter().find_map(|k| rest.strip_prefix(k))?;
    let end = r
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(r.len());
    (end > 0).then(|| &r[..end])
}

fn is_word(text: &str, name: &str) -> bool {
    text.match_indices(name).any(|(at, _)| {
        let before = text[..at].chars().next_back();
        let after = text[at + name.len()..].chars().next();
        let ident = |c: Option<char>| c.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_');
        !ident(before) && !ident(after)
    })
}

#[test]
fn every_public_library_item_has_a_caller() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut all = Vec::new();
    for d in ["src", "python", "tests", "benches", "fuzz"] {
        files(&root.join(d), &mut all);
    }
    let texts: Vec<(PathBuf, String)> = all
        .into_iter()
        .map(|p| {
            let t = std::fs::read_to_string(&p).unwrap();
            (p, t)
        })
        .collect();
    let code: Vec<(&Path, Vec<(usize, &str)>)> = texts
        .iter()
        .map(|(p, t)| (p.as_path(), code_lines(t)))
        .collect();
    let cli = root.join("src/cli");
    let mut declarations = 0;
    let mut uncalled = Vec::new();
    for (p, lines) in &code {
        if !p.starts_with(root.join("src")) || p.starts_with(&cli) || p.extension().unwrap() != "rs"
        {
            continue;
        }
        for (n, l) in lines {
            let Some(name) = declared(l) else { continue };
            declarations += 1;
            let called = code.iter().any(|(q, other)| {
                other
                    .iter()
                    .any(|(m, o)| (q != p || m != n) && is_word(o, name))
            });
            if !called {
                uncalled.push(format!(
                    "{}:{n} {name}",
                    p.strip_prefix(root).unwrap().display()
                ));
            }
        }
    }
    assert!(declarations > 500, "only {declarations} public items found");
    assert!(
        uncalled.is_empty(),
        "public items nothing calls (remove them, or use them):\n{}",
        uncalled.join("\n")
    );
}
