//! The recipes of docs/dataset.md run as written: the Slurm array script maps its index to a
//! shard, and the GNU parallel recipe builds the same dataset as one build.

use super::build::{assert_same_tree, bin, build, ok, write_config, TINY};
use crate::common;
use common::stderr;
use std::path::Path;
use std::process::{Command, Stdio};

fn doc_block(marker: &str) -> String {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/dataset.md"))
            .unwrap();
    doc.split("```bash\n")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
        .find(|b| b.contains(marker))
        .unwrap_or_else(|| panic!("docs/dataset.md has no bash block with {marker}"))
        .to_string()
}

/// PATH with the directory of the freshly built `psns` first.
fn path_with_psns() -> String {
    let dir = Path::new(bin()).parent().unwrap();
    format!(
        "{}:{}",
        dir.display(),
        std::env::var("PATH").unwrap_or_default()
    )
}

#[test]
fn slurm_script_parses_and_maps_the_array_index_to_the_shard() {
    let t = tempfile::tempdir().unwrap();
    let script = t.path().join("psns-dataset.sbatch");
    std::fs::write(&script, doc_block("#SBATCH")).unwrap();
    let n = Command::new("bash")
        .arg("-n")
        .arg(&script)
        .output()
        .unwrap();
    assert!(
        n.status.success(),
        "bash -n: {}",
        String::from_utf8_lossy(&n.stderr)
    );
    let cfg = write_config(t.path(), TINY);
    let whole = t.path().join("whole");
    ok(&build(&whole, &cfg, &["--jobs", "1"]));
    // an array --array=4-6: task ids 4, 5, 6 are shards 1/3, 2/3, 3/3
    let out = t.path().join("slurm");
    for id in [6, 4, 5] {
        let o = Command::new("bash")
            .arg(&script)
            .env("PATH", path_with_psns())
            .env("OUT", &out)
            .env("CONFIG", &cfg)
            .env("SLURM_ARRAY_TASK_ID", id.to_string())
            .env("SLURM_ARRAY_TASK_MIN", "4")
            .env("SLURM_ARRAY_TASK_COUNT", "3")
            .env("SLURM_CPUS_PER_TASK", "1")
            .output()
            .unwrap();
        ok(&o);
        assert!(
            stderr(&o).contains(&format!("shard {}/3", id - 3)),
            "task {id}: {}",
            stderr(&o)
        );
    }
    assert_same_tree(&whole, &out);
    // outside an array the script refuses to run
    let o = Command::new("bash")
        .arg(&script)
        .env("PATH", path_with_psns())
        .env_remove("SLURM_ARRAY_TASK_COUNT")
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("job array"), "{}", stderr(&o));
}

#[test]
fn gnu_parallel_recipe_builds_the_same_dataset() {
    let have = Command::new("parallel")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !have {
        common::missing(
            "gnu_parallel_recipe_builds_the_same_dataset",
            "GNU parallel is not installed (apt-get install parallel)",
        );
        return;
    }
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(t.path(), TINY);
    let whole = t.path().join("whole");
    ok(&build(&whole, &cfg, &["--jobs", "1"]));
    let script = t.path().join("recipe.sh");
    std::fs::write(
        &script,
        format!("set -euo pipefail\n{}", doc_block("parallel ")),
    )
    .unwrap();
    let out = t.path().join("par");
    let o = Command::new("bash")
        .arg(&script)
        .env("PATH", path_with_psns())
        .env("OUT", &out)
        .env("CONFIG", &cfg)
        .env("N", "3")
        .env("HOME", t.path()) // parallel writes ~/.parallel
        .output()
        .unwrap();
    ok(&o);
    assert!(
        stderr(&o).contains("files present and intact"),
        "{}",
        stderr(&o)
    );
    assert_same_tree(&whole, &out);
}
