//! Running the CLI in a scratch folder.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A scratch folder removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("ossify-it-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
    pub fn path(&self, rel: &str) -> PathBuf {
        self.0.join(rel)
    }

    /// `run INPUT --out <scratch>/out --cache <scratch>/cache`: the pipeline into this folder.
    pub fn run_args(&self, input: &Path) -> Vec<String> {
        let path = |p: PathBuf| p.to_str().expect("UTF-8 path").to_string();
        vec![
            "run".into(),
            path(input.to_path_buf()),
            "--out".into(),
            path(self.path("out")),
            "--cache".into(),
            path(self.path("cache")),
        ]
    }

    /// Runs the pipeline on `input` into this folder with `--set SET`, asserting that it
    /// fails with each of `says` on stderr and writes no skeleton.
    pub fn run_refused(&self, input: &Path, set: &str, says: &[&str]) {
        let mut args = self.run_args(input);
        args.extend(["--set".into(), set.into()]);
        let result = xtask(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(!result.status.success(), "--set {set} ran");
        let stderr = String::from_utf8_lossy(&result.stderr);
        for part in says {
            assert!(stderr.contains(part), "{part:?} not in: {stderr}");
        }
        assert!(!self.path("out").join("skeleton.json").exists());
    }

    /// Runs the pipeline on `input` into this folder, asserting success; the output folder.
    pub fn run(&self, input: &Path) -> PathBuf {
        let args = self.run_args(input);
        xtask_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        self.path("out")
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The project root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Runs `xtask ARGS` from the project root.
pub fn xtask(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("the xtask binary runs")
}

/// Runs `xtask ARGS`, asserting success, and returns stdout.
pub fn xtask_ok(args: &[&str]) -> String {
    let out = xtask(args);
    assert!(
        out.status.success(),
        "xtask {args:?} failed:\nstdout: {}\nstderr: {}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("stdout is UTF-8")
}

/// Reads a JSON file.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The mean over frames of the distance between two joints' positions (mm), where both are known.
pub fn mean_distance(a: &serde_json::Value, b: &serde_json::Value) -> Option<f64> {
    let (a, b) = (a.as_array()?, b.as_array()?);
    let mut sum = 0.0;
    let mut n = 0usize;
    for (p, q) in a.iter().zip(b) {
        let (Some(p), Some(q)) = (p.as_array(), q.as_array()) else {
            continue;
        };
        let d: f64 = p
            .iter()
            .zip(q)
            .map(|(x, y)| (x.as_f64().unwrap() - y.as_f64().unwrap()).powi(2))
            .sum();
        sum += d.sqrt();
        n += 1;
    }
    (n > 0).then(|| sum / n as f64)
}
