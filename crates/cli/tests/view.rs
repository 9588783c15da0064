//! `locap view` end to end: the generated page opened in headless Chromium.
//!
//! Chromium's own command line is the driver (no npm in CI): `--dump-dom` with a virtual time
//! budget returns the DOM once the page's scripts are done, and the viewer reports its state
//! as data attributes on `<body>`; `--screenshot` captures the WebGL canvas (rendered with
//! SwiftShader, so no GPU is needed). `.ci/run` installs the Debian `chromium` package; where
//! it is missing the test is skipped with a message, except in CI (env `CI` set), where it
//! fails.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn locap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_locap"))
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn shared_data() -> Option<PathBuf> {
    let dir = repo().join("../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("CI").is_some() {
        panic!("../shared/data not found, and CI needs it");
    } else {
        eprintln!("skipping: ../shared/data not found (tests on real captures need it)");
        None
    }
}

/// The Chromium binary: `$LOCAP_CHROMIUM`, else `chromium` / `chromium-browser` on PATH.
fn chromium() -> Option<PathBuf> {
    let candidates: Vec<PathBuf> = match std::env::var_os("LOCAP_CHROMIUM") {
        Some(path) => vec![PathBuf::from(path)],
        None => std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())
            .flat_map(|dir| [dir.join("chromium"), dir.join("chromium-browser")])
            .collect(),
    };
    match candidates.into_iter().find(|p| p.is_file()) {
        Some(path) => Some(path),
        None if std::env::var_os("CI").is_some() => panic!("chromium not found, and CI needs it (.ci/run installs it)"),
        None => {
            eprintln!("skipping: chromium not found (install the Debian package `chromium`, or set LOCAP_CHROMIUM)");
            None
        }
    }
}

const WINDOW: (u32, u32) = (1100, 800);

/// Runs headless Chromium on `url` with `extra` arguments; returns standard output. A fresh
/// profile per run, nothing that talks to the network, WebGL through SwiftShader.
fn run_chromium(browser: &Path, url: &str, extra: &[String]) -> String {
    let profile = tempfile::tempdir().unwrap();
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--hide-scrollbars",
            &format!("--window-size={},{}", WINDOW.0, WINDOW.1),
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(extra)
        .arg(url)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // A hung browser must not hang the test suite.
    let started = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > Duration::from_secs(90) {
            let _ = child.kill();
            panic!("chromium did not finish within 90 s on {url}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The data attributes of `<body>` in a DOM dump.
fn body_state(dom: &str) -> std::collections::HashMap<String, String> {
    let start = dom.find("<body").expect("a <body> in the DOM dump");
    let tag = &dom[start..start + dom[start..].find('>').unwrap()];
    tag.split(" data-")
        .skip(1)
        .filter_map(|attr| {
            let (name, value) = attr.split_once('=')?;
            Some((name.to_string(), value.trim_matches('"').to_string()))
        })
        .collect()
}

fn state_at(browser: &Path, page: &Path, frame: usize) -> std::collections::HashMap<String, String> {
    let url = format!("file://{}#frame={frame}", page.display());
    let state = body_state(&run_chromium(browser, &url, &["--dump-dom".to_string()]));
    assert_eq!(state.get("error"), None, "the page reports an error: {state:?}");
    assert_eq!(state.get("ready").map(String::as_str), Some("1"), "page not ready: {state:?}");
    state
}

/// RGB pixels of a screenshot of `page` at `frame`.
fn screenshot(browser: &Path, page: &Path, frame: usize, png_path: &Path) -> (u32, u32, Vec<u8>) {
    let url = format!("file://{}#frame={frame}", page.display());
    run_chromium(browser, &url, &[format!("--screenshot={}", png_path.display())]);
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(png_path).expect("a screenshot")));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let rgb: Vec<u8> = buf[..info.buffer_size()].chunks(channels).flat_map(|p| [p[0], p[1], p[2]]).collect();
    (info.width, info.height, rgb)
}

/// Pixels of the 3D view (the upper part of the page, above the timeline) that are marker
/// blue: blue clearly above red and green, far from the dark background and grey lines.
fn marker_pixels(width: u32, rgb: &[u8]) -> usize {
    let view_rows = 420; // the view is ~470 px tall at 1100x800; stay clear of the timeline
    rgb.chunks(3)
        .take(width as usize * view_rows)
        .filter(|p| {
            let (r, g, b) = (i32::from(p[0]), i32::from(p[1]), i32::from(p[2]));
            b > 140 && b > r + 40 && b > g + 20
        })
        .count()
}

/// The issue's acceptance test: a page for CMU take 85_02 opens, draws one sphere per
/// visible marker at the first frame, and moving to another frame (`#frame=N`) changes the
/// frame and the image.
#[test]
fn page_opens_in_chromium_and_draws_the_markers() {
    let Some(data) = shared_data() else { return };
    let Some(browser) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let take_path = data.join("cmu-c3d/85_02.c3d");
    let page = dir.path().join("85_02.html");
    let out = locap().arg("view").arg(&take_path).arg("-o").arg(&page).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let take = locap_io::c3d::read_path(&take_path).unwrap().to_take().unwrap();
    let visible_at = |f: usize| (0..take.marker_count()).filter(|m| take.is_valid(f, *m)).count().to_string();

    let first = state_at(&browser, &page, 0);
    assert_eq!(first["frame"], "0");
    assert_eq!(first["spheres"], visible_at(0), "{first:?}");
    assert_eq!(first["spheres"], "41");
    let later = state_at(&browser, &page, 600);
    assert_eq!(later["frame"], "600");
    assert_eq!(later["spheres"], visible_at(600));
    // Past the end clamps to the last frame.
    assert_eq!(state_at(&browser, &page, 100_000)["frame"], (take.frame_count() - 1).to_string());

    let (w, h, a) = screenshot(&browser, &page, 0, &dir.path().join("a.png"));
    assert_eq!((w, h), WINDOW);
    let (_, _, b) = screenshot(&browser, &page, 600, &dir.path().join("b.png"));
    // 41 spheres of ~5 px radius: hundreds of marker-blue pixels, not a blank canvas.
    let (pa, pb) = (marker_pixels(w, &a), marker_pixels(w, &b));
    assert!(pa > 300 && pb > 300, "marker pixels: {pa}, {pb}");
    let changed = a.chunks(3).zip(b.chunks(3)).take(w as usize * 420).filter(|(p, q)| p != q).count();
    assert!(changed > 500, "frames 0 and 600 look the same ({changed} pixels differ)");
    if let Some(keep) = std::env::var_os("LOCAP_KEEP_SCREENSHOT") {
        std::fs::copy(dir.path().join("b.png"), keep).unwrap();
    }
}

/// A take cleaned by `locap clean`, compared with its raw version: the page colours filled
/// samples as such (the counts the page reports equal those of LOCAP:FILLED at that frame),
/// and reports the distance to the compared take.
#[test]
fn page_shows_what_clean_filled() {
    let Some(browser) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let raw = repo().join("examples/cmu_01_01_last10s.c3d");
    let cleaned = dir.path().join("clean.c3d");
    assert!(locap().arg("clean").arg(&raw).arg("-o").arg(&cleaned).output().unwrap().status.success());
    let page = dir.path().join("clean.html");
    let out = locap().arg("view").arg(&cleaned).arg("--compare").arg(&raw).arg("-o").arg(&page).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let file = locap_io::c3d::read_path(&cleaned).unwrap();
    let take = file.to_take().unwrap();
    let states = locap_view::sample_states(
        &take,
        &file.parameters.continued_strings("LOCAP", "FILLED"),
        &file.parameters.continued_strings("LOCAP", "OUTLIERS"),
    )
    .unwrap();
    let m = take.marker_count();
    let count = |f: usize, s: locap_view::SampleState| states[f * m..(f + 1) * m].iter().filter(|x| **x == s).count();
    let frame =
        (0..take.frame_count()).find(|f| count(*f, locap_view::SampleState::Filled) > 0).expect("a filled frame");
    let state = state_at(&browser, &page, frame);
    assert_eq!(state["filled"], count(frame, locap_view::SampleState::Filled).to_string(), "{state:?}");
    assert_eq!(state["outlier"], count(frame, locap_view::SampleState::OutlierFixed).to_string());
    let missing = count(frame, locap_view::SampleState::Missing);
    assert_eq!(state["missing"], missing.to_string());
    assert_eq!(state["spheres"], (m - missing).to_string());
    // The raw take inside a real gap: the missing marker is not a sphere but a ghost where it
    // was last seen.
    let raw_page = dir.path().join("raw.html");
    assert!(locap().arg("view").arg(&raw).arg("-o").arg(&raw_page).output().unwrap().status.success());
    let raw_take = locap_io::c3d::read_path(&raw).unwrap().to_take().unwrap();
    let gap_frame = (0..raw_take.frame_count())
        .find(|f| (0..m).filter(|k| !raw_take.is_valid(*f, *k)).count() >= 2)
        .expect("the example has frames with a real gap besides the never-seen RBAC-1");
    let missing = (0..m).filter(|k| !raw_take.is_valid(gap_frame, *k)).count();
    let raw_state = state_at(&browser, &raw_page, gap_frame);
    assert_eq!(raw_state["missing"], missing.to_string(), "{raw_state:?}");
    assert_eq!(raw_state["spheres"], (m - missing).to_string());
    // Markers never seen in the take (the split label `RBAC-1`) have no last position.
    let seen = |k: usize| (0..raw_take.frame_count()).any(|f| raw_take.is_valid(f, k));
    let ghosts = (0..m).filter(|k| !raw_take.is_valid(gap_frame, *k) && seen(*k)).count();
    assert!(ghosts >= 1);
    assert_eq!(raw_state["ghosts"], ghosts.to_string());

    let (errors, _) =
        locap_view::page::per_frame_error_mm(&take, &locap_io::c3d::read_path(&raw).unwrap().to_take().unwrap())
            .unwrap();
    let shown: f64 = state["error-mm"].parse().unwrap();
    assert!((shown - errors[frame].unwrap()).abs() < 0.01, "{shown} vs {:?}", errors[frame]);
}

/// Bad combinations are reported clearly: a motion with other frames than the take fails the
/// take (exit 1) with both frame counts; `--motion` with several takes is a usage error.
#[test]
fn view_reports_mismatched_inputs() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let take = repo().join("examples/cmu_01_01_last10s.c3d");
    let bvh = data.join("cmu-bvh/131_01.bvh");
    let out = locap()
        .arg("view")
        .arg(&take)
        .arg("--motion")
        .arg(&bvh)
        .arg("-o")
        .arg(dir.path().join("x.html"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("the --motion file has") && stderr.contains("but the take has 1200"), "{stderr}");
    assert!(!dir.path().join("x.html").exists(), "no page for a failed take");
    let out =
        locap().arg("view").arg(&take).arg(&take).arg("--motion").arg(&bvh).arg("-o").arg(dir.path()).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("single take"));
}

/// `locap plot gaps` and `locap plot fill` write the charts (a real benchmark report).
#[test]
fn plot_writes_charts() {
    let dir = tempfile::tempdir().unwrap();
    let take = repo().join("examples/cmu_01_01_last10s.c3d");
    let out = locap().args(["plot", "gaps"]).arg(&take).arg("-o").arg(dir.path()).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for name in ["gap-lengths.png", "occlusion-rates.png"] {
        let bytes = std::fs::read(dir.path().join(name)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG"), "{name}");
    }
    let report = dir.path().join("fill.json");
    let out = locap().args(["bench", "fill"]).arg(&take).arg("--json").arg(&report).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let svg = dir.path().join("fill.svg");
    let out = locap().args(["plot", "fill"]).arg(&report).arg("-o").arg(&svg).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("\nedm\n") && text.contains("\nlinear\n"), "the legend names the methods");
    let not_a_report = dir.path().join("other.json");
    std::fs::write(&not_a_report, r#"{"markers": 3}"#).unwrap();
    let out = locap().args(["plot", "fill"]).arg(&not_a_report).arg("-o").arg(&svg).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a report"));
}

/// `--motion`: CMU's solved motion of take 01_01 (AMC converted to BVH by `locap convert`)
/// is drawn on its markers: in the page's data the root joint stays within a few cm of the
/// hip markers' centre on every frame (this pins the Z-up to Y-up convention), and the browser
/// draws every joint.
#[test]
fn skeleton_overlays_the_markers() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bvh = dir.path().join("01_01.bvh");
    let amc = data.join("cmu-asfamc/01/01_01.amc");
    let out = locap()
        .arg("convert")
        .arg(&amc)
        .arg(&bvh)
        .arg("--asf")
        .arg(data.join("cmu-asfamc/01/01.asf"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let page = dir.path().join("01_01.html");
    let take = data.join("cmu-c3d/01_01.c3d");
    let out = locap().arg("view").arg(&take).arg("--motion").arg(&bvh).arg("-o").arg(&page).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let parsed = locap_view::page::ParsedPage::parse(&std::fs::read_to_string(&page).unwrap()).unwrap();
    let frames = parsed.meta["frames"].as_u64().unwrap() as usize;
    let markers: Vec<&str> = parsed.meta["markers"].as_array().unwrap().iter().map(|m| m.as_str().unwrap()).collect();
    let joints = parsed.meta["skeleton"]["joints"].as_array().unwrap().len();
    let q = parsed.quantiser().unwrap();
    let steps = |name: &str| -> Vec<i16> {
        parsed.block(name).unwrap().chunks_exact(2).map(|b| i16::from_le_bytes([b[0], b[1]])).collect()
    };
    let positions = locap_view::encode::decode_tracks(&steps("positions"), markers.len(), frames, &q);
    let skeleton = locap_view::encode::decode_tracks(&steps("joints"), joints, frames, &q);
    let hips: Vec<usize> =
        ["LFWT", "RFWT", "LBWT", "RBWT"].iter().map(|n| markers.iter().position(|m| m == n).unwrap()).collect();
    let worst = (0..frames)
        .map(|f| {
            let centre = hips.iter().map(|&k| positions[k][f]).sum::<locap_core::Vec3>() / 4.0;
            (skeleton[0][f] - centre).norm()
        })
        .fold(0.0, f64::max);
    assert!(worst < 80.0, "root {worst:.0} mm from the hip markers' centre");

    let Some(browser) = chromium() else { return };
    let state = state_at(&browser, &page, 1000);
    assert_eq!(state["joints"], joints.to_string());
    assert_eq!(joints, 38, "31 joints and 7 end sites");
}

/// A folder in, a folder of pages out (mirroring the input names); `--edges 0` leaves the
/// neighbour edges out.
#[test]
fn view_writes_one_page_per_take_of_a_folder() {
    let dir = tempfile::tempdir().unwrap();
    let out = locap()
        .arg("view")
        .arg(repo().join("examples"))
        .arg("--edges")
        .arg("0")
        .arg("-o")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let page = dir.path().join("cmu_01_01_last10s.html");
    let parsed = locap_view::page::ParsedPage::parse(&std::fs::read_to_string(&page).unwrap()).unwrap();
    assert_eq!(parsed.meta["frames"], 1200);
    assert_eq!(parsed.meta["first_frame"], 1591);
    assert_eq!(parsed.meta["edges"].as_array().unwrap().len(), 0);
    assert!(String::from_utf8_lossy(&out.stdout).contains("1200 frames, 42 markers"));

    // TRC takes too (every sample captured or missing: TRC has no LOCAP parameters).
    let trc = dir.path().join("take.trc");
    assert!(
        locap().arg("convert").arg(repo().join("examples/cmu_01_01_last10s.c3d")).arg(&trc).status().unwrap().success()
    );
    let trc_page = dir.path().join("trc.html");
    let out = locap().arg("view").arg(&trc).arg("-o").arg(&trc_page).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let parsed = locap_view::page::ParsedPage::parse(&std::fs::read_to_string(&trc_page).unwrap()).unwrap();
    assert_eq!(parsed.meta["frames"], 1200);
    assert_eq!(parsed.meta["state_counts"][1], 0, "nothing filled");
}
