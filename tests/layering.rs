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
        for (i, line) in text.lines().enumerate() {
            let mut rest = line;
            while let Some(k) = rest.find("crate::") {
                rest = &rest[k + 7..];
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if let Some(&l) = layer.get(name.as_str()) {
                    if l > own && name != module {
                        violations.push(format!(
                            "{}:{}: {module} (layer {own}) imports {name} (layer {l})",
                            rel.display(),
                            i + 1
                        ));
                    }
                }
                if name == "cli" {
                    violations.push(format!(
                        "{}:{}: the library uses the front-end",
                        rel.display(),
                        i + 1
                    ));
                }
            }
        }
    }
    assert!(
        violations.is_empty(),
        "layering violations:\n{}",
        violations.join("\n")
    );
}
