//! The library's layering (docs/architecture.md): a module may import only from its own or lower
//! layers, so there is no import cycle; and the library never reaches into the binary's front-end.

use std::collections::HashMap;
use std::path::Path;

const LAYERS: &[(&str, u32)] = &[
    ("error", 0),
    ("angle", 0),
    ("image", 0),
    ("rng", 0),
    ("simd", 0),
    ("vmath", 0),
    ("memory", 0),
    ("names", 0),
    ("progress", 0),
    ("record", 0),
    ("sun", 1),
    ("world", 1),
    ("sky", 2),
    ("camera", 3),
    ("render", 4),
    ("sensor", 5),
    ("stokes", 6),
    ("demosaic", 7),
    ("stream", 8),
    ("trajectory", 8),
    ("heading", 8),
    ("gige", 8),
    ("config", 9),
    ("io", 9),
    ("ros2", 9),
    ("pipeline", 10),
    ("dataset", 11),
    ("options", 12),
];

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            if p.file_name().unwrap() != "cli" {
                rust_files(&p, out);
            }
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The paths a source text names through `crate::` or `super::`, with their (1-based) line,
/// each item of a grouped import expanded (`use super::{a, b::{C, d}}` is `super::a`,
/// `super::b::C` and `super::b::d`, nested or spread over several lines); a glob ends at its
/// module (`super::x::*` is `super::x`), `self` in a group is the group's path. Line comments and
/// `$crate::` are skipped.
fn use_paths(text: &str) -> Vec<(usize, String)> {
    // the text without line comments, each byte's line number kept
    let mut code = String::new();
    let mut line_of = Vec::new();
    for (i, l) in text.lines().enumerate() {
        let l = match l.find("//") {
            Some(k) => &l[..k],
            None => l,
        };
        code.push_str(l);
        code.push('\n');
        line_of.extend(std::iter::repeat_n(i + 1, l.len() + 1));
    }
    let b = code.as_bytes();
    let is_ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let skip_ws = |mut i: usize| {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        i
    };
    // one use tree at `i` below `prefix`: its expanded paths into `out`; returns where it ends
    fn tree(
        b: &[u8],
        mut i: usize,
        prefix: String,
        out: &mut Vec<(usize, String)>,
        skip_ws: &dyn Fn(usize) -> usize,
        is_ident: &dyn Fn(u8) -> bool,
    ) -> usize {
        let start = skip_ws(i);
        let mut path = prefix;
        i = start;
        loop {
            i = skip_ws(i);
            if i < b.len() && b[i] == b'{' {
                i += 1;
                loop {
                    i = skip_ws(i);
                    if i >= b.len() || b[i] == b'}' {
                        return i + 1;
                    }
                    i = tree(b, i, path.clone(), out, skip_ws, is_ident);
                    i = skip_ws(i);
                    if i < b.len() && b[i] == b',' {
                        i += 1;
                    } else if i < b.len() && b[i] != b'}' {
                        return i; // not a use tree after all
                    }
                }
            }
            let s = i;
            while i < b.len() && is_ident(b[i]) {
                i += 1;
            }
            let seg = std::str::from_utf8(&b[s..i]).unwrap();
            if !seg.is_empty() && seg != "self" {
                path.push_str("::");
                path.push_str(seg);
            }
            if seg.is_empty() || !b[i..].starts_with(b"::") {
                out.push((start, path));
                return i;
            }
            i += 2;
        }
    }
    let mut out = Vec::new();
    let mut from = 0;
    while from < b.len() {
        let next = ["crate::", "super::"]
            .iter()
            .filter_map(|p| code[from..].find(p).map(|k| (from + k, *p)))
            .min();
        let Some((at, prefix)) = next else { break };
        from = at + prefix.len();
        let before = code[..at].bytes().last();
        if before.is_some_and(|c| is_ident(c) || c == b':' || c == b'$') {
            continue; // `$crate::`, or part of a longer path
        }
        let mut root = prefix.trim_end_matches("::").to_string();
        let mut i = from;
        while b[i..].starts_with(b"super::") {
            root.push_str("::super");
            i += 7;
        }
        let mut found = Vec::new();
        from = tree(b, i, root, &mut found, &skip_ws, &is_ident);
        for (pos, path) in found {
            out.push((line_of[pos.min(line_of.len() - 1)], path));
        }
    }
    out
}

/// The top modules a source text names through `crate::` ([`use_paths`]), with their line.
fn crate_modules(text: &str) -> Vec<(usize, String)> {
    let mut out: Vec<(usize, String)> = use_paths(text)
        .into_iter()
        .filter_map(|(l, p)| {
            let top = p.strip_prefix("crate::")?.split("::").next()?.to_string();
            Some((l, top))
        })
        .collect();
    out.dedup();
    out
}

/// The reader sees grouped imports, nested and over several lines, and ignores comments and
/// `$crate::`.
#[test]
fn grouped_imports_are_read() {
    let text = "use crate::sky::Sky;\nuse crate::{render, sensor::{fast, Sensor}};\nuse crate::{\n    pipeline::RawPipeline,\n    dataset,\n};\n// crate::options\nlet x = $crate::simd::simd();\n";
    let got = crate_modules(text);
    let want: Vec<(usize, String)> = [
        (1, "sky"),
        (2, "render"),
        (2, "sensor"),
        (4, "pipeline"),
        (5, "dataset"),
    ]
    .iter()
    .map(|&(l, n)| (l, n.to_string()))
    .collect();
    assert_eq!(got, want);
}

#[test]
fn library_modules_import_only_lower_layers() {
    let layer: HashMap<&str, u32> = LAYERS.iter().copied().collect();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    let declared: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.strip_prefix("pub mod "))
        .map(|l| l.trim_end_matches(';'))
        .collect();
    for m in &declared {
        assert!(
            layer.contains_key(m),
            "module {m} has no layer in docs/architecture.md"
        );
    }
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut violations = Vec::new();
    for f in files {
        let rel = f.strip_prefix(&src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_str()
            .unwrap();
        let module = first.trim_end_matches(".rs");
        let Some(&own) = layer.get(module) else {
            continue; // lib.rs, main.rs
        };
        let text = std::fs::read_to_string(&f).unwrap();
        for (line, name) in crate_modules(&text) {
            if let Some(&l) = layer.get(name.as_str()) {
                if l > own && name != module {
                    violations.push(format!(
                        "{}:{line}: {module} (layer {own}) imports {name} (layer {l})",
                        rel.display()
                    ));
                }
            }
            if name == "cli" {
                violations.push(format!(
                    "{}:{line}: the library uses the front-end",
                    rel.display()
                ));
            }
        }
    }
    assert!(
        violations.is_empty(),
        "layering violations:\n{}",
        violations.join("\n")
    );
}

/// The library's module path of a source file: `src/a/b.rs` and `src/a/b/mod.rs` are `a::b`.
fn module_path(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_str().unwrap().to_string())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" {
        parts.push(stem.to_string());
    }
    parts
}

/// No import cycle at any level: between the library's top modules, and between the sibling
/// submodules of every module (`sensor::fast` and `sensor::normal` may not use each other both
/// ways). A use of a parent by its child, or the reverse, is not an edge: a module and its
/// children are one unit.
#[test]
fn no_module_imports_another_that_imports_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut texts = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        if rel == Path::new("lib.rs") || rel == Path::new("main.rs") {
            continue;
        }
        let text = std::fs::read_to_string(f).unwrap();
        texts.push((module_path(rel), rel.display().to_string(), text));
    }
    let cycles = import_cycles(&texts);
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}

/// The cycle test reads every item of a grouped import, not only the first, for `super::` and
/// `crate::` alike, nested and over several lines.
#[test]
fn a_cycle_through_a_grouped_import_is_caught() {
    let file = |m: &str, text: &str| {
        let path: Vec<String> = m.split("::").map(String::from).collect();
        (path, format!("{m}.rs"), text.to_string())
    };
    let texts = vec![
        file("a", "pub mod x;\npub mod y;\npub mod w;\n"),
        file("a::w", "pub struct W;\n"),
        file("a::x", "use super::{w::W, y::Y};\n"),
        file("a::y", "use super::{\n    w,\n    x::{self, X},\n};\n"),
        file("p", "use crate::{a::w::W, q::Q};\n"),
        file("q", "use crate::{a, p::{self}};\n"),
    ];
    let cycles = import_cycles(&texts);
    assert_eq!(
        cycles,
        [
            "a: x and y import each other (a::x.rs:1, a::y.rs:3)",
            "crate: p and q import each other (p.rs:1, q.rs:1)",
        ]
    );
    // the same without the groups' later items: no cycle
    let texts: Vec<_> = texts
        .into_iter()
        .map(|(m, f, t)| (m, f, t.replace(", y::Y", "").replace(", q::Q", "")))
        .collect();
    assert!(import_cycles(&texts).is_empty());
}

/// The import cycles among `texts` (module path, file name, source), each with the lines that
/// make it.
fn import_cycles(texts: &[(Vec<String>, String, String)]) -> Vec<String> {
    let modules: std::collections::HashSet<Vec<String>> =
        texts.iter().map(|(m, _, _)| m.clone()).collect();
    // edges between siblings: (parent, from child, to child) -> a line that makes it
    let mut edges: HashMap<(Vec<String>, String, String), String> = HashMap::new();
    for (m, rel, text) in texts {
        for (line, p) in use_paths(text) {
            let mut segs = p.split("::");
            let mut path = match segs.next() {
                Some("crate") => Vec::new(),
                _ => m[..m.len() - 1].to_vec(), // `super` of a file's module is its parent
            };
            let mut segs = segs.peekable();
            while segs.peek() == Some(&"super") {
                segs.next();
                path.pop();
            }
            for seg in segs {
                let mut next = path.clone();
                next.push(seg.to_string());
                if !modules.contains(&next) {
                    break;
                }
                path = next;
            }
            let t = path;
            let common = m.iter().zip(&t).take_while(|(a, b)| a == b).count();
            if common < m.len() && common < t.len() {
                let key = (m[..common].to_vec(), m[common].clone(), t[common].clone());
                edges.entry(key).or_insert_with(|| format!("{rel}:{line}"));
            }
        }
    }
    let mut cycles = Vec::new();
    for ((parent, a, b), at) in &edges {
        if a < b {
            if let Some(back) = edges.get(&(parent.clone(), b.clone(), a.clone())) {
                cycles.push(format!(
                    "{}: {a} and {b} import each other ({at}, {back})",
                    if parent.is_empty() {
                        "crate".to_string()
                    } else {
                        parent.join("::")
                    }
                ));
            }
        }
    }
    // longer cycles: a path from a module back to itself through its siblings
    let mut by_parent: HashMap<Vec<String>, HashMap<String, Vec<String>>> = HashMap::new();
    for (parent, a, b) in edges.keys() {
        by_parent
            .entry(parent.clone())
            .or_default()
            .entry(a.clone())
            .or_default()
            .push(b.clone());
    }
    for (parent, graph) in &by_parent {
        for start in graph.keys() {
            let mut stack = vec![(start.clone(), vec![start.clone()])];
            let mut seen = std::collections::HashSet::new();
            while let Some((n, trail)) = stack.pop() {
                for next in graph.get(&n).into_iter().flatten() {
                    if next == start && trail.len() > 2 {
                        cycles.push(format!(
                            "{}: cycle {} -> {start}",
                            parent.join("::"),
                            trail.join(" -> ")
                        ));
                    } else if seen.insert(next.clone()) {
                        let mut t = trail.clone();
                        t.push(next.clone());
                        stack.push((next.clone(), t));
                    }
                }
            }
        }
    }
    cycles.sort();
    cycles.dedup();
    cycles
}
