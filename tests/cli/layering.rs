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
    ("sun", 1),
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

/// The top modules a source text names through `crate::`, with their (1-based) line: plain
/// paths (`crate::sky::Sky`) and every item of a grouped import (`use crate::{sky, sensor::X}`,
/// nested or spread over several lines). Comments are skipped.
fn crate_modules(text: &str) -> Vec<(usize, String)> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
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
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find("crate::") {
        let at = from + k;
        from = at + 7;
        let before = code[..at].chars().last();
        if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':' || c == '$') {
            continue; // `$crate::`, or part of a longer path
        }
        let rest = &code[from..];
        if let Some(group) = rest.strip_prefix('{') {
            // the group's top-level items, up to its closing brace
            let (mut depth, mut item_start, mut i) = (0usize, 0usize, 0usize);
            let bytes = group.as_bytes();
            while i < bytes.len() {
                match bytes[i] {
                    b'{' => depth += 1,
                    b'}' if depth == 0 => break,
                    b'}' => depth -= 1,
                    b',' if depth == 0 => {
                        let item = group[item_start..i].trim_start();
                        let pos = from + 1 + i - item.len();
                        out.push((line_of[pos.min(line_of.len() - 1)], ident(item)));
                        item_start = i + 1;
                    }
                    _ => {}
                }
                i += 1;
            }
            let item = group[item_start..i].trim_start();
            if !item.is_empty() {
                let pos = from + 1 + i - item.len();
                out.push((line_of[pos.min(line_of.len() - 1)], ident(item)));
            }
        } else {
            out.push((line_of[at], ident(rest)));
        }
    }
    out.retain(|(_, n)| !n.is_empty());
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
    let mut modules: std::collections::HashSet<Vec<String>> = Default::default();
    let mut texts = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        if rel == Path::new("lib.rs") || rel == Path::new("main.rs") {
            continue;
        }
        let m = module_path(rel);
        modules.insert(m.clone());
        texts.push((m, rel.to_path_buf(), std::fs::read_to_string(f).unwrap()));
    }
    // edges between siblings: (parent, from child, to child) -> a line that makes it
    let mut edges: HashMap<(Vec<String>, String, String), String> = HashMap::new();
    for (m, rel, text) in &texts {
        for (i, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            let mut targets = Vec::new();
            for (prefix, base) in [("crate::", Vec::new()), ("super::", m.clone())] {
                let mut rest = line;
                while let Some(k) = rest.find(prefix) {
                    let before = rest[..k].chars().last();
                    rest = &rest[k + prefix.len()..];
                    if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':') {
                        continue; // `$crate::`, or part of a longer path
                    }
                    let mut path = base.clone();
                    if prefix == "super::" {
                        // `super` of a file's module is its parent
                        path.pop();
                        let mut r = rest;
                        while let Some(x) = r.strip_prefix("super::") {
                            path.pop();
                            r = x;
                        }
                        rest = r;
                    }
                    for seg in rest.split("::") {
                        let name: String = seg
                            .chars()
                            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                            .collect();
                        let mut next = path.clone();
                        next.push(name.clone());
                        if name.is_empty() || !modules.contains(&next) {
                            break;
                        }
                        path = next;
                        if seg.len() != name.len() {
                            break;
                        }
                    }
                    if !path.is_empty() {
                        targets.push(path);
                    }
                }
            }
            for t in targets {
                let common = m.iter().zip(&t).take_while(|(a, b)| a == b).count();
                if common < m.len() && common < t.len() {
                    let key = (m[..common].to_vec(), m[common].clone(), t[common].clone());
                    edges
                        .entry(key)
                        .or_insert_with(|| format!("{}:{}", rel.display(), i + 1));
                }
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
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}
