//! Data safety of every command (issue 14): no output ever replaces an input, however its path
//! is spelled; batch outputs that collide are refused before any work; folder walks survive
//! link loops and stay inside the folder; pipes are refused, not opened; an interrupted write
//! leaves no temporary file; absurd option values are usage errors (exit 2), bad files are
//! failed takes (exit 1).

mod common;

use common::{locap, repo, shared_data};
use std::path::{Path, PathBuf};
use std::process::Output;

fn example() -> PathBuf {
    repo().join("examples/cmu_01_01_last10s.c3d")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A folder `d` holding a copy of the example take as `d/t.c3d`; returns (root, input).
fn folder_with_take() -> (tempfile::TempDir, PathBuf) {
    let root = tempfile::tempdir().unwrap();
    let d = root.path().join("d");
    std::fs::create_dir(&d).unwrap();
    let input = d.join("t.c3d");
    std::fs::copy(example(), &input).unwrap();
    (root, input)
}

/// Ways of naming `d/t.c3d` from `root`: relative with `./`, with `..`, absolute, a symbolic
/// link and a hard link. The plain spelling is the input itself.
fn spellings(root: &Path) -> Vec<String> {
    let mut out = vec!["./d/t.c3d".to_string(), "d/../d/t.c3d".to_string()];
    out.push(std::fs::canonicalize(root.join("d/t.c3d")).unwrap().display().to_string());
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(root.join("d/t.c3d"), root.join("link.c3d")).unwrap();
        std::fs::hard_link(root.join("d/t.c3d"), root.join("hard.c3d")).unwrap();
        out.push("link.c3d".into());
        out.push("hard.c3d".into());
    }
    out
}

fn assert_refused(out: &Output, input: &Path, before: &[u8], what: &str) {
    assert_eq!(out.status.code(), Some(2), "{what}: {}", stderr(out));
    assert!(stderr(out).contains("never overwrites its input"), "{what}: {}", stderr(out));
    assert_eq!(std::fs::read(input).unwrap(), before, "{what}: the input changed");
}

/// Every command that writes a file per take, with the output naming the input four ways.
#[test]
fn no_command_overwrites_its_input_under_any_spelling() {
    let (root, input) = folder_with_take();
    let before = std::fs::read(&input).unwrap();
    let names = spellings(root.path());
    for name in &names {
        let cases: Vec<(&str, Vec<&str>)> = vec![
            ("convert", vec!["convert", "d/t.c3d", name]),
            ("clean", vec!["clean", "d/t.c3d", "-o", name]),
            ("unlabel", vec!["unlabel", "d/t.c3d", "-o", name]),
            ("label", vec!["label", "d/t.c3d", "--template", "d/t.c3d", "-o", name]),
            ("view", vec!["view", "d/t.c3d", "-o", name]),
            ("solve --markers-out", vec!["solve", "d/t.c3d", "-o", "x.bvh", "--markers-out", name]),
            ("stats", vec!["stats", "d/t.c3d", "-o", name]),
            ("bench fill --json", vec!["bench", "fill", "d/t.c3d", "--json", name, "--no-neural"]),
            ("layout fit", vec!["layout", "fit", "--layout", "lay.toml", "--take", "d/t.c3d", "-o", name]),
        ];
        std::fs::write(root.path().join("lay.toml"), "").unwrap();
        for (what, args) in cases {
            let out = locap().args(&args).current_dir(root.path()).output().unwrap();
            assert_refused(&out, &input, &before, &format!("{what} -> {name}"));
        }
    }
    assert!(!root.path().join("x.bvh").exists(), "nothing was written before the refusal");
}

/// Auxiliary inputs are inputs too: a model, a layout, a motion.
#[test]
fn auxiliary_inputs_are_never_overwritten() {
    let root = tempfile::tempdir().unwrap();
    let take = root.path().join("t.c3d");
    std::fs::copy(example(), &take).unwrap();
    let layout = root.path().join("cmu41.toml");
    std::fs::copy(repo().join("crates/synth/layouts/cmu41.toml"), &layout).unwrap();
    let before = std::fs::read(&layout).unwrap();
    let out = locap()
        .args(["layout", "fit", "--layout", "cmu41.toml", "--take", "t.c3d", "-o", "./cmu41.toml"])
        .current_dir(root.path())
        .output()
        .unwrap();
    assert_refused(&out, &layout, &before, "layout fit -o its --layout");

    // synth -o into the folder that holds its --motion: walk.bvh would be rewritten.
    if let Some(data) = shared_data() {
        let motion = root.path().join("walk.bvh");
        std::fs::copy(data.join("cmu-bvh/131_01.bvh"), &motion).unwrap();
        let before = std::fs::read(&motion).unwrap();
        let out = locap().args(["synth", "--motion", "walk.bvh", "-o", "."]).current_dir(root.path()).output().unwrap();
        assert_refused(&out, &motion, &before, "synth -o the motion's folder");
    }

    // eval --json onto the model it evaluates.
    let model = root.path().join("m.locapsv");
    std::fs::write(&model, b"model").unwrap();
    let out = locap()
        .args(["eval", "--data", ".", "--models", "m.locapsv", "--json", "./m.locapsv"])
        .current_dir(root.path())
        .output()
        .unwrap();
    assert_refused(&out, &model, b"model", "eval --json its model");

    // train fill --out a training file.
    let before = std::fs::read(&take).unwrap();
    let out = locap()
        .args(["train", "fill", "--data", "t.c3d", "--out", "./t.c3d"])
        .current_dir(root.path())
        .output()
        .unwrap();
    assert_refused(&out, &take, &before, "train fill --out its data");
}

/// Batch outputs: into the input folder itself, or two inputs onto one output, are refused
/// before any take is processed.
#[test]
fn colliding_batch_outputs_are_refused_before_any_work() {
    let (root, input) = folder_with_take();
    let before = std::fs::read(&input).unwrap();
    for args in
        [vec!["convert", "d", "d", "--to", "c3d"], vec!["clean", "d", "-o", "./d"], vec!["clean", "d", "-o", "d"]]
    {
        let out = locap().args(&args).current_dir(root.path()).output().unwrap();
        assert_refused(&out, &input, &before, &args.join(" "));
        let names: Vec<_> = std::fs::read_dir(root.path().join("d")).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 1, "{}: left {names:?}", args.join(" "));
    }

    // take.c3d and take.trc would both become out/take.csv.
    let out = locap().args(["convert", "d/t.c3d", "d/t.trc"]).current_dir(root.path()).output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let out = locap().args(["convert", "d", "out", "--to", "csv"]).current_dir(root.path()).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("same file"), "{}", stderr(&out));
    assert!(!root.path().join("out").join("t.csv").exists(), "nothing was converted");
}

/// A link loop and a link to the parent inside an input folder: the walk ends, takes are read
/// once, nothing outside the folder is read.
#[cfg(unix)]
#[test]
fn folder_walks_do_not_follow_links_to_folders() {
    let (root, _) = folder_with_take();
    let d = root.path().join("d");
    std::fs::create_dir(d.join("sub")).unwrap();
    std::os::unix::fs::symlink(&d, d.join("sub/loop")).unwrap();
    std::os::unix::fs::symlink("..", d.join("up")).unwrap();
    // Outside the folder: must not be read.
    std::fs::copy(example(), root.path().join("outside.c3d")).unwrap();
    let out = locap().args(["info", "d", "--json"]).current_dir(root.path()).output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let paths: Vec<&str> = match &json {
        serde_json::Value::Array(items) => items.iter().map(|i| i["path"].as_str().unwrap()).collect(),
        one => vec![one["path"].as_str().unwrap()],
    };
    assert_eq!(paths, ["d/t.c3d"], "each take once, nothing outside the folder");

    let cleaned = root.path().join("cleaned");
    let out =
        locap().args(["clean", "d", "-o", "cleaned", "--outliers", "off"]).current_dir(root.path()).output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let mut written = Vec::new();
    let mut stack = vec![cleaned];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() { stack.push(path) } else { written.push(path) }
        }
    }
    assert_eq!(written.len(), 1, "{written:?}");
}

/// A named pipe given or found in a folder is refused without being opened (opening one
/// blocks until a writer comes).
#[cfg(unix)]
#[test]
fn named_pipes_are_refused_not_opened() {
    let (root, _) = folder_with_take();
    let status = std::process::Command::new("mkfifo").arg(root.path().join("d/pipe.c3d")).status().unwrap();
    assert!(status.success());
    let out = locap().args(["info", "d/pipe.c3d"]).current_dir(root.path()).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("pipe.c3d") && stderr(&out).contains("not a regular file"), "{}", stderr(&out));
    // In a folder: the pipe is reported, the take beside it is described.
    let out = locap().args(["info", "d"]).current_dir(root.path()).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("t.c3d"));
    // As an auxiliary input.
    let out = locap()
        .args(["label", "d/t.c3d", "--template", "d/pipe.c3d", "-o", "x.c3d"])
        .current_dir(root.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("not a regular file"), "{}", stderr(&out));
}

/// One missing path in a batch is reported as `path: reason`; the other takes go on.
#[test]
fn a_missing_path_does_not_stop_the_batch() {
    let (root, _) = folder_with_take();
    let out = locap().args(["info", "missing.c3d", "d/t.c3d"]).current_dir(root.path()).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("missing.c3d"), "{}", stderr(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("d/t.c3d"), "the other take is described");
    let out = locap()
        .args(["clean", "missing.c3d", "d/t.c3d", "-o", "out", "--outliers", "off"])
        .current_dir(root.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(
        root.path().join("out/t.c3d").exists() || root.path().join("out/d/t.c3d").exists(),
        "the good take was cleaned"
    );
}

/// Option values that cannot make sense are usage errors naming the option, refused before
/// any allocation or work.
#[test]
fn absurd_option_values_are_usage_errors() {
    let take = example();
    let take = take.to_str().unwrap();
    let cases: Vec<Vec<&str>> = vec![
        vec!["synth", "--motion", "x.bvh", "-o", "out", "--rate", "1e9"],
        vec!["synth", "--motion", "x.bvh", "-o", "out", "--rate", "nan"],
        vec!["convert", "x.amc", "x.bvh", "--amc-rate", "0"],
        vec!["convert", "x.amc", "x.bvh", "--amc-rate=-120"],
        vec!["train", "fill", "--data", take, "--hidden", "100000"],
        vec!["train", "fill", "--data", take, "--batch", "100000"],
        vec!["train", "solve", "--data", take, "--global", "100000"],
        vec!["train", "solve", "--data", take, "--channels", "100000"],
        vec!["hands", take, "-o", "out", "--procedural", "1000000"],
        vec!["hands", take, "-o", "out", "--dorsal-mm", "nan"],
        vec!["bench", "label", take, "--ghosts", "100000"],
        vec!["unlabel", take, "-o", "x.c3d", "--fps", "nan"],
        vec!["clean", take, "-o", "x.c3d", "--body-threshold=-1"],
        vec!["label", take, "--template", take, "-o", "x.c3d", "--fit-distance", "1e308"],
    ];
    for args in cases {
        let out = locap().args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{}: {}", args.join(" "), stderr(&out));
        let option = args.iter().rev().find(|a| a.starts_with("--")).unwrap().split('=').next().unwrap();
        assert!(stderr(&out).contains(option), "{}: the message names {option}: {}", args.join(" "), stderr(&out));
    }
    // A solved motion goes to a motion format only: `-o x.c3d` is refused, not silently a BVH.
    let dir = tempfile::tempdir().unwrap();
    let c3d = dir.path().join("x.c3d");
    let out = locap().args(["solve", take, "-o"]).arg(&c3d).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(!c3d.exists());
}

/// SIGTERM in the middle of writing a large output: the program exits, and neither the output
/// nor its temporary file is left.
#[cfg(unix)]
#[test]
fn an_interrupted_write_leaves_no_temporary_file() {
    use locap_core::{MarkerName, Take, Vec3};
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.trc");
    // 41 markers x 200,000 frames: long enough to write as CSV that the signal lands mid-write.
    let names: Vec<MarkerName> = (0..41).map(|i| MarkerName::parse(&format!("M{i:02}"))).collect();
    let frames = 200_000;
    let mut take = Take::empty(names, frames, 120.0).unwrap();
    for f in 0..frames {
        for m in 0..41 {
            let t = f as f64 / 120.0;
            take.set_position_mm(f, m, Some(Vec3::new(m as f64 * 10.0 + t.sin(), t.cos() * 100.0, 1000.0 + t)))
                .unwrap();
        }
    }
    locap_io::trc::write_trc_path(&take, locap_core::LengthUnit::Millimetre, &big).unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let mut child = locap().arg("convert").arg(&big).arg(out_dir.join("big.csv")).spawn().unwrap();
    let temporary = || {
        std::fs::read_dir(&out_dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .any(|e| e.file_name().to_string_lossy().starts_with(".locap-"))
    };
    let mut seen = false;
    for _ in 0..60_000 {
        if temporary() {
            seen = true;
            break;
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    assert!(seen, "the conversion finished before its temporary file was seen; make the take longer");
    let kill = std::process::Command::new("kill").arg("-TERM").arg(child.id().to_string()).status().unwrap();
    assert!(kill.success());
    let status = child.wait().unwrap();
    assert!(!status.success(), "the interrupted conversion reports failure");
    let left: Vec<_> = std::fs::read_dir(&out_dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}
