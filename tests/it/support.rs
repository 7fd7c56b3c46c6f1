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

/// Each segment's marker labels in skeleton.json, sorted, without those starting with
/// `prefix` (markers added beside a capture; "" leaves every one in), the groups sorted,
/// empty ones left out.
pub fn groups_without(skeleton: &serde_json::Value, prefix: &str) -> Vec<Vec<String>> {
    let mut groups: Vec<Vec<String>> = skeleton["segments"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            let mut g: Vec<String> = s["markers"]
                .as_array()
                .unwrap()
                .iter()
                .map(|m| m.as_str().unwrap().to_string())
                .filter(|m| prefix.is_empty() || !m.starts_with(prefix))
                .collect();
            g.sort();
            g
        })
        .filter(|g| !g.is_empty())
        .collect();
    groups.sort();
    groups
}

/// CMU 02_01's walk as read, or `None` (skipped loudly, for the test `what`) without the
/// shared data.
pub fn cmu_02_01(what: &str) -> Option<mocap_io::Trajectories> {
    let data = mocap_io::testdata::shared_data_dir(what)?;
    let options = mocap_io::ReadOptions::default();
    let capture = mocap_io::read_capture(&data.join("c3d/cmu/02_01.c3d"), &options).unwrap();
    Some(capture.trajectories)
}
