//! `locap solve` and `locap eval` as a user runs them, with the shipped solver.

mod common;

use common::{locap, repo, shared_data, tracking};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A real CMU take solved to BVH: our reader and a third-party Python BVH parser (`bvh` from
/// PyPI, installed by `.ci/run` into `.ci/pydeps`) read back the take's frame count and rate;
/// the cleaned markers come out complete.
#[test]
fn solve_writes_bvh_with_the_takes_frames_and_rate() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (bvh, clean) = (dir.path().join("02_01.bvh"), dir.path().join("02_01.clean.c3d"));
    let take = data.join("cmu-c3d/02_01.c3d");
    let out = locap().arg("solve").arg(&take).arg("-o").arg(&bvh).arg("--markers-out").arg(&clean).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("343 frames at 120 Hz"), "{text}");
    // The default refines the network's answer with the kinematic solver (`locap_nn::method`):
    // measured, every wrist joint within 60 mm of its markers' mean (the network alone: 51%)
    // and no joint turning more than 20 degrees between frames.
    assert!(text.contains("network refined by the kinematic solver"), "{text}");
    let (over, wrists) = tracking(&text);
    assert_eq!(over, 0, "{text}");
    assert!(wrists.is_some_and(|w| w >= 99.0), "{text}");
    let motion = locap_io::bvh::read_bvh_path(&bvh, locap_core::LengthUnit::Centimetre).unwrap();
    assert_eq!(motion.frame_count(), 343);
    assert!((motion.frame_rate_hz() - 120.0).abs() < 1e-6);
    assert_eq!(motion.skeleton.index_of("ltibia").map(|i| motion.skeleton.joints()[i].parent), Some(Some(2)));
    let cleaned_file = locap_io::c3d::read_path(&clean).unwrap();
    let cleaned = cleaned_file.to_take().unwrap();
    assert_eq!((cleaned.frame_count(), cleaned.missing_count()), (343, 0));
    // The fill (here the outlier windows the cleaning removed and refilled) is recorded as
    // `locap clean` records it: `LABEL first-last` per filled run.
    let filled = locap_core::range_list::decode(&cleaned_file.parameters.continued_strings("LOCAP", "FILLED")).unwrap();
    assert!(!filled.is_empty() && filled.iter().all(|r| r.split_whitespace().count() == 2), "{filled:?}");
    // The whole record, as `locap clean` writes it: the outlier windows behind those fills and
    // the method.
    let record = cleaned_file.provenance(&cleaned).unwrap();
    assert!(!record.outliers.is_empty(), "{record:?}");
    assert!(cleaned_file.parameters.get("LOCAP", "SWAPS").is_some());
    assert!(record.method.as_deref().unwrap_or_default().starts_with("locap solve: "), "{record:?}");

    let pydeps = repo().join(".ci/pydeps");
    // The cleaned markers keep the input file's parameter groups and analog data (ezc3d, the
    // reference C3D reader, reads both files).
    let script = "import sys, ezc3d, numpy as np; a = ezc3d.c3d(sys.argv[1]); b = ezc3d.c3d(sys.argv[2]); \
                  ga = set(a['parameters'].keys()); gb = set(b['parameters'].keys()); \
                  assert ga <= gb, ga - gb; \
                  assert a['data']['analogs'].shape == b['data']['analogs'].shape, (a['data']['analogs'].shape, b['data']['analogs'].shape); \
                  assert np.array_equal(a['data']['analogs'], b['data']['analogs']); \
                  assert a['parameters']['POINT']['LABELS']['value'] == b['parameters']['POINT']['LABELS']['value']; print(sorted(ga))";
    match Command::new("python3").arg("-c").arg(script).arg(&take).arg(&clean).env("PYTHONPATH", &pydeps).output() {
        Ok(out) if out.status.success() => eprintln!("ezc3d: groups kept {}", String::from_utf8_lossy(&out.stdout)),
        Ok(out) if String::from_utf8_lossy(&out.stderr).contains("No module named") => {
            assert!(std::env::var_os("CI").is_none(), "CI must install ezc3d into .ci/pydeps");
            eprintln!("skipping the ezc3d check: ezc3d not importable from {}", pydeps.display());
        }
        Ok(out) => panic!("ezc3d: the cleaned markers lost something: {}", String::from_utf8_lossy(&out.stderr)),
        Err(e) => eprintln!("skipping the ezc3d check: no python3 ({e})"),
    }
    let script = "import sys; from bvh import Bvh; m = Bvh(open(sys.argv[1]).read()); \
                  assert m.nframes == 343, m.nframes; assert abs(m.frame_time - 1 / 120) < 1e-9, m.frame_time; \
                  assert len(m.get_joints_names()) == 31; print('bvh ok')";
    match Command::new("python3").arg("-c").arg(script).arg(&bvh).env("PYTHONPATH", &pydeps).output() {
        Ok(out) if out.status.success() => {}
        Ok(out) if String::from_utf8_lossy(&out.stderr).contains("No module named") => {
            assert!(std::env::var_os("CI").is_none(), "CI must install bvh into .ci/pydeps");
            eprintln!("skipping the Python BVH check: bvh not importable from {}", pydeps.display());
        }
        Ok(out) => panic!("the Python BVH parser rejects the file: {}", String::from_utf8_lossy(&out.stderr)),
        Err(e) => eprintln!("skipping the Python BVH check: no python3 ({e})"),
    }

    // Not a model, or a take of another marker set: clear errors, nothing written.
    let bad = dir.path().join("bad.locapsv");
    std::fs::write(&bad, b"not a model").unwrap();
    let out = locap()
        .arg("solve")
        .arg(&take)
        .arg("-o")
        .arg(dir.path().join("x.bvh"))
        .arg("--model")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("LOCAPSV"), "{}", String::from_utf8_lossy(&out.stderr));
    let other = data.join("numediart-c3d/03_rolling.c3d");
    let out = locap().arg("solve").arg(&other).arg("-o").arg(dir.path().join("y.bvh")).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("another marker set"));
    assert!(!dir.path().join("x.bvh").exists() && !dir.path().join("y.bvh").exists());
}

/// CMU 02_01's motion (subject 02, held out of every model's training) synthesized as training
/// shards under `dir`, 5% occlusion with the real gap statistics; the shard folder.
fn synthesized_02_01(data: &Path, dir: &Path, seed: &str) -> PathBuf {
    let shards = dir.join("test");
    let out = locap()
        .args(["synth", "--format", "shard", "--p-occ", "0.05", "--seed", seed, "--motion"])
        .arg(data.join("cmu-asfamc/02/02_01.amc"))
        .arg("--augment")
        .arg(data.join("gap-stats/real-gap-statistics.json"))
        .arg("-o")
        .arg(&shards)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    shards
}

/// `locap eval` on a held-out synthetic take: the Table-1 rows (a model and an ensemble of two),
/// JSON, charts, and the real-take comparison with CMU's own solution.
#[test]
fn eval_prints_table_one() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let shards = synthesized_02_01(&data, dir.path(), "3");
    let (json, plots) = (dir.path().join("t1.json"), dir.path().join("plots"));
    let eval = || {
        let mut c = locap();
        c.arg("eval").arg("--data").arg(&shards).arg("--models").arg(repo().join("models/solver-cmu41.locapsv"));
        c.arg("--real").arg(data.join("cmu-c3d/02_01.c3d"));
        c
    };
    let out = eval()
        .arg("--ensemble")
        .arg(repo().join("models/solver-cmu41.locapsv"))
        .arg(repo().join("models/solver-cmu41-v2.locapsv"))
        .arg("--reference")
        .arg(data.join("cmu-asfamc/02/02_01.amc"))
        .arg("--json")
        .arg(&json)
        .arg("--plots")
        .arg(&plots)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("JOE (deg)") && text.contains("JPE (mm)") && text.contains("OMPE (mm)"), "{text}");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let method = &report["methods"][0];
    assert_eq!(method["name"], "solver-cmu41");
    // The shipped solver on an unseen subject: centimetres, not decimetres, of joint error.
    let (jpe, joe) = (method["jpe_mm"].as_f64().unwrap(), method["joe_deg"].as_f64().unwrap());
    assert!(jpe > 1.0 && jpe < 80.0 && joe > 0.5 && joe < 30.0, "JPE {jpe} mm, JOE {joe} deg");
    // The ensemble is a column of its own, named by its members.
    let ensemble = &report["methods"][1];
    assert_eq!(ensemble["name"], "solver-cmu41&solver-cmu41-v2");
    let ensemble_joe = ensemble["joe_deg"].as_f64().unwrap();
    assert!(ensemble_joe > 0.5 && ensemble_joe < 30.0 && ensemble_joe != joe, "{ensemble_joe} deg");
    let real = &report["real"][0]["comparison"];
    assert_eq!(real["frames"], 343);
    assert!(real["jpe_mm"].as_f64().unwrap() < 100.0, "{real}");
    for name in ["error-by-gap-length.svg", "error-by-gap-length.png", "solver-cmu41-jpe-per-joint.svg"] {
        assert!(plots.join(name).is_file(), "{name}");
    }
    // References must pair with takes.
    let out = eval().output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("one reference per take"));
    // A refine or offset prior that is not a weight, or a prior window that is not a time, is
    // refused, naming the option.
    for (given, named) in [
        ("--refine-prior=-1", "--refine-prior -1"),
        ("--prior-window=nan", "--prior-window NaN"),
        ("--offset-prior=-1", "--offset-prior -1"),
    ] {
        let out = eval()
            .arg("--reference")
            .arg(data.join("cmu-asfamc/02/02_01.amc"))
            .args(["--kinematic", "--refine", given])
            .output()
            .unwrap();
        assert!(!out.status.success());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(named), "{stderr}");
    }
}

/// Issue 17's tracking checks on long real takes, solved as a user solves them: no joint turns
/// more than 20 degrees between consecutive frames where the markers move smoothly, and the
/// wrist joints stay within 60 mm of their markers.
/// - CMU 01_01 (2751 frames): a motion no model trained on. Measured: 0 frame pairs (largest
///   9.9 degrees), 100% of the wrists.
/// - CMU 85_12 (4499 frames): another subject, whose motion the built-in models learned only as
///   the kinematic solver solved it (models/README.md). Measured: 1 pair, 20.7 degrees at the
///   left foot (frames 3152-3153; 20.1 with the third model alone), 100% of the wrists. The foot's markers are not moving as a
///   foot does there: over frames 3146-3153 the ankle-to-toe distance goes 132 -> 78 -> 204
///   mm (151 mm median over the take) and the heel-to-toe one 199 -> 143 -> 228 mm (223).
///   Before two-axis joints were held on the products of their turns (`locap_label::ik`),
///   the foot could not follow them: 0 pairs, largest 16.3 degrees.
#[test]
fn the_default_solve_holds_joints_steady_and_wrists_on_their_markers() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    for (take, jumps) in [("01_01", 0), ("85_12", 1)] {
        let (c3d, bvh) = (data.join(format!("cmu-c3d/{take}.c3d")), dir.path().join(format!("{take}.bvh")));
        let out = locap().arg("solve").arg(&c3d).arg("-o").arg(&bvh).output().unwrap();
        assert!(out.status.success(), "{take}: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        let (over, wrists) = tracking(&text);
        assert!(over <= jumps, "{text}");
        assert!(wrists.is_some_and(|w| w >= 99.0), "{text}");
        let unexplained = jumps_where_markers_hold(&c3d, &bvh);
        assert!(unexplained.is_empty(), "{take}: frame pairs over 20 degrees where the markers hold: {unexplained:?}");
    }
}

/// The frame pairs `(f, f + 1)` where a joint of the motion at `bvh` turns more than 20 degrees
/// while the markers of the take at `c3d` move smoothly: within 3 frames of the pair, no two
/// markers that keep their distance over the take (standard deviation under 10 mm: one
/// segment or neighbouring ones) are more than 60 mm from their median distance. A marker
/// that leaves its segment like that is mislabeled or a ghost, and the check leaves
/// those frames out. Measured: on 01_01 no frame is left out; on 85_12, 86 of 4499.
fn jumps_where_markers_hold(c3d: &Path, bvh: &Path) -> Vec<(usize, String)> {
    let take = locap_io::c3d::read_path(c3d).unwrap().to_take().unwrap();
    let motion = locap_io::bvh::read_bvh_path(bvh, locap_core::LengthUnit::Centimetre).unwrap();
    let (frames, markers) = (take.frame_count(), take.marker_count());
    assert_eq!(motion.frame_count(), frames);
    let distance = |f: usize, a: usize, b: usize| Some((take.position_mm(f, a)? - take.position_mm(f, b)?).norm());
    // The pairs that keep their distance, with its median.
    let mut steady: Vec<(usize, usize, f64)> = Vec::new();
    for a in 0..markers {
        for b in a + 1..markers {
            let mut d: Vec<f64> = (0..frames).filter_map(|f| distance(f, a, b)).collect();
            if d.len() < frames / 2 {
                continue;
            }
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
            d.sort_by(f64::total_cmp);
            if sd < 10.0 {
                steady.push((a, b, d[d.len() / 2]));
            }
        }
    }
    let breaks = |f: usize| {
        (f.saturating_sub(3)..(f + 4).min(frames))
            .any(|g| steady.iter().any(|&(a, b, median)| distance(g, a, b).is_some_and(|d| (d - median).abs() > 60.0)))
    };
    let every_joint = vec![true; motion.skeleton.len()];
    locap_eval::solver::rotation_jumps_over(&motion, &every_joint, 20.0)
        .into_iter()
        .filter(|&(f, _)| !breaks(f))
        .map(|(f, j)| (f, motion.skeleton.joints()[j].name.clone()))
        .collect()
}

/// The later body models on the real take of the subject no model was trained on, against CMU's
/// own solution: the second (`models/solver-cmu41-v2.locapsv`: mirrored motions and wider
/// subject variation, models/README.md) and the third (`models/solver-cmu41-v3.locapsv`: also
/// motion solved from four more real takes) turn the joints closer than the first
/// (`models/solver-cmu41.locapsv`), which is why they ship (the three answer together as the
/// built-in solver). (They do not place them closer: docs/benchmarks.md, "Neural solver,
/// second model" and "third model".)
#[test]
fn the_later_body_models_turn_joints_closer_to_cmus_solution() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let solved_against_cmu = |model: Option<&str>| {
        let bvh = dir.path().join("02_01.bvh");
        let mut c = locap();
        // The networks alone, not refined (the default): their own rotations are compared.
        c.arg("solve").arg(data.join("cmu-c3d/02_01.c3d")).args(["--method", "network", "-o"]).arg(&bvh);
        if let Some(m) = model {
            c.arg("--model").arg(repo().join(m));
        }
        let out = c.output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        common::bvh_against_cmu(&bvh, &data, "02", "02_01")
    };
    let first = solved_against_cmu(Some("models/solver-cmu41.locapsv"));
    let second = solved_against_cmu(Some("models/solver-cmu41-v2.locapsv"));
    eprintln!(
        "02_01 vs CMU AMC: first model JOE {:.2} deg JPE {:.1} mm; second model JOE {:.2} deg JPE {:.1} mm",
        first.joe_deg, first.jpe_mm, second.joe_deg, second.jpe_mm
    );
    // Measured here (every joint, the fixed ones included) 7.48 against 5.55 degrees; `locap
    // eval` (EDM cleaning, the rotating joints) 10.52 against 7.82.
    assert!(second.joe_deg < 0.85 * first.joe_deg, "{second:?} against {first:?}");
    // Positions: 23.2 against 25.7 mm (both ways of measuring); a model that solved another
    // skeleton or frame would be decimetres off.
    assert!(second.jpe_mm < 35.0, "{second:?}");
    // The third (`locap eval` 7.45 degrees, 28.1 mm; here 5.30 degrees): the same holds.
    let third = solved_against_cmu(Some("models/solver-cmu41-v3.locapsv"));
    eprintln!("third model JOE {:.2} deg JPE {:.1} mm", third.joe_deg, third.jpe_mm);
    assert!(third.joe_deg < 0.85 * first.joe_deg, "{third:?} against {first:?}");
    assert!(third.jpe_mm < 35.0, "{third:?}");
}

/// The built-in solver is the three body models as one ensemble: `--model` given three times
/// (third, second, first) solves a take to the same BVH, byte for byte. Models of another
/// marker set or skeleton do not join: the command fails naming the file.
#[test]
fn the_built_in_solver_is_the_three_models_as_one() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let take = data.join("cmu-c3d/02_01.c3d");
    let solve = |models: &[&str], out: &Path| {
        let mut c = locap();
        c.arg("solve").arg(&take).args(["--method", "network", "-o"]).arg(out);
        for m in models {
            c.arg("--model").arg(repo().join(m));
        }
        c.output().unwrap()
    };
    let (built_in, given) = (dir.path().join("built-in.bvh"), dir.path().join("given.bvh"));
    let three = ["models/solver-cmu41-v3.locapsv", "models/solver-cmu41-v2.locapsv", "models/solver-cmu41.locapsv"];
    for (models, out) in [(&[][..], &built_in), (&three[..], &given)] {
        let run = solve(models, out);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    }
    assert_eq!(std::fs::read(&built_in).unwrap(), std::fs::read(&given).unwrap());
    // The third model alone answers otherwise: the members are used.
    let alone = dir.path().join("alone.bvh");
    assert!(solve(&three[..1], &alone).status.success());
    assert_ne!(std::fs::read(&built_in).unwrap(), std::fs::read(&alone).unwrap());
    let mixed = dir.path().join("mixed.bvh");
    let run = solve(&["models/solver-cmu41-v3.locapsv", "models/solver-hand-left.locapsv"], &mixed);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("solver-hand-left.locapsv") && err.contains("skeleton"), "{err}");
    assert!(!mixed.exists());
}

/// The refinement on a template moved halfway to the skeleton the network predicts for the
/// take (the default) places the joints of a held-out subject's synthesized take closer to
/// the truth than on the template alone (`--network-skeleton 0`). Measured on 02_01 (seed 7,
/// 5% real-statistics occlusion): JPE 12.2 against 14.2 mm (docs/benchmarks.md, "The network's
/// skeleton in the refinement").
#[test]
fn the_refinement_on_the_networks_skeleton_places_joints_closer() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let shards = synthesized_02_01(&data, dir.path(), "7");
    let refined_jpe = |share: Option<&str>| {
        let json = dir.path().join("t1.json");
        let mut c = locap();
        c.arg("eval").arg("--data").arg(&shards).arg("--models").arg(repo().join("models/solver-cmu41-v3.locapsv"));
        c.args(["--kinematic", "--refine", "--json"]).arg(&json);
        if let Some(share) = share {
            c.args(["--network-skeleton", share]);
        }
        let out = c.output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let refined = report["methods"].as_array().unwrap().iter().find(|m| m["name"] == "solver-cmu41-v3+ik").cloned();
        refined.unwrap()["jpe_mm"].as_f64().unwrap()
    };
    let (template, default) = (refined_jpe(Some("0")), refined_jpe(None));
    eprintln!("02_01 refined JPE: template {template:.2} mm, default {default:.2} mm");
    assert!(default < template - 1.0, "default {default} mm against the template's {template} mm");
    // The refused settings: the command fails and says why.
    let refused = |extra: &[&std::ffi::OsStr]| -> String {
        let out = locap()
            .arg("eval")
            .arg("--data")
            .arg(&shards)
            .arg("--models")
            .arg(repo().join("models/solver-cmu41-v3.locapsv"))
            .args(["--kinematic", "--refine"])
            .args(extra)
            .output()
            .unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // A share outside 0 to 1 is refused, naming the option.
    assert!(refused(&["--network-skeleton".as_ref(), "1.5".as_ref()]).contains("--network-skeleton 1.5"));
    // A layout's skeleton is the user's: the share does not apply, and saying it is refused
    // rather than ignored.
    let err = refused(&["--network-skeleton".as_ref(), "0.5".as_ref(), "--kinematic-layout".as_ref(), shards.as_ref()]);
    assert!(err.contains("--network-skeleton") && err.contains("--kinematic-layout"), "{err}");
}

/// A studio solves onto the skeleton it calibrated for the subject: `--skeleton SUBJECT.asf`
/// (no `--layout`) puts the CMU layout on that subject's own bones. On CMU 02_01 with subject
/// 02's ASF the kinematic solver comes closer to CMU's own solution (measured JPE 17.0 mm
/// against 18.7 on the template skeleton with the trunk's markers held; docs/benchmarks.md,
/// "The subject's own skeleton" and "The trunk's markers held"),
/// and the BVH carries the subject's bones. A skeleton in another unit is refused, naming
/// the file.
#[test]
fn the_subjects_own_skeleton_places_joints_closer_to_cmus_solution() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let asf = data.join("cmu-asfamc/02/02.asf");
    let solve = |skeleton: Option<&Path>, bvh: &Path| {
        let mut c = locap();
        c.arg("solve").arg(data.join("cmu-c3d/02_01.c3d")).args(["--method", "ik", "-o"]).arg(bvh);
        if let Some(s) = skeleton {
            c.arg("--skeleton").arg(s);
        }
        c.output().unwrap()
    };
    let (own, template) = (dir.path().join("own.bvh"), dir.path().join("template.bvh"));
    for (skeleton, bvh) in [(Some(asf.as_path()), &own), (None, &template)] {
        let out = solve(skeleton, bvh);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let (own_jpe, template_jpe) = (
        common::bvh_against_cmu(&own, &data, "02", "02_01").jpe_mm,
        common::bvh_against_cmu(&template, &data, "02", "02_01").jpe_mm,
    );
    assert!(own_jpe < template_jpe - 1.0, "own bones {own_jpe:.1} mm, template {template_jpe:.1} mm");
    // The thigh (the `ltibia` joint's offset) is subject 02's, within the calibration's small
    // correction.
    let subject = locap_io::asf_amc::read_asf_path(&asf).unwrap();
    let subject = subject.to_skeleton(subject.mm_per_unit()).unwrap();
    let solved = locap_io::bvh::read_bvh_path(&own, locap_core::LengthUnit::Centimetre).unwrap().skeleton;
    let tibia = |s: &locap_core::Skeleton| s.joints()[s.index_of("ltibia").unwrap()].offset_mm.norm();
    assert!((tibia(&solved) / tibia(&subject) - 1.0).abs() < 0.05, "{} vs {}", tibia(&solved), tibia(&subject));
    // A CMU BVH's skeleton read as centimetres is five times too small.
    let bvh = data.join("cmu-bvh/131_01.bvh");
    let out = solve(Some(&bvh), &dir.path().join("units.bvh"));
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("131_01.bvh") && stderr.contains("another length unit"), "{stderr}");
    // The network alone solves on its own skeleton: a skeleton given to it is refused.
    let out = locap()
        .arg("solve")
        .arg(data.join("cmu-c3d/02_01.c3d"))
        .args(["--method", "network", "--skeleton"])
        .arg(&asf)
        .arg("-o")
        .arg(dir.path().join("network.bvh"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--skeleton goes with the kinematic solver"));
}
