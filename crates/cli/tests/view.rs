//! `locap view` end to end: the generated page opened in headless Chromium.
//!
//! Chromium's own command line is the driver (no npm in CI): `--dump-dom` with a virtual time
//! budget returns the DOM once the page's scripts are done, and the viewer reports its state
//! as data attributes on `<body>`; `--screenshot` captures the WebGL canvas (rendered with
//! SwiftShader, so no GPU is needed). Virtual time runs no animation frames, so playback,
//! keys, clicks and hover are tested in real time through the DevTools protocol (`mod cdp`,
//! a minimal WebSocket client over `--remote-debugging-port`). `.ci/run` installs the Debian `chromium` package; where
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
    locap_testkit::shared_data()
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

/// Headless, a fresh profile per run (added by the callers), nothing that talks to the
/// network, WebGL through SwiftShader (no GPU needed).
const CHROMIUM_FLAGS: [&str; 10] = [
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
];

/// Runs headless Chromium on `url` with `extra` arguments; returns standard output. A fresh
/// profile per run, nothing that talks to the network, WebGL through SwiftShader.
fn run_chromium(browser: &Path, url: &str, extra: &[String]) -> String {
    let profile = tempfile::tempdir().unwrap();
    let mut child = Command::new(browser)
        .args(CHROMIUM_FLAGS)
        .args(["--hide-scrollbars", &format!("--window-size={},{}", WINDOW.0, WINDOW.1), "--virtual-time-budget=5000"])
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
    let states = locap_view::sample_states(&take, &file.provenance(&take).unwrap());
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
    let copy = dir.path().join("copy.c3d");
    std::fs::copy(&take, &copy).unwrap();
    let out = locap().arg("view").arg(&copy).arg("-o").arg(&copy).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "an output that is the input is a usage error");
    assert!(String::from_utf8_lossy(&out.stderr).contains("never overwrites its input"));
    assert_eq!(std::fs::read(&copy).unwrap(), std::fs::read(&take).unwrap());
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
    assert_eq!(out.status.code(), Some(1), "a bad report file is not a usage error");
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

/// A minimal client of the Chrome DevTools protocol (JSON over one WebSocket), enough to
/// press keys, click and read values in a page: what a user does, without npm tooling.
mod cdp {
    use std::io::{BufRead, BufReader, Read, Write};
    use std::net::TcpStream;
    use std::process::{Child, Command, Stdio};
    use std::time::{Duration, Instant};

    /// A headless Chromium with remote debugging, and a WebSocket to its page.
    pub struct Browser {
        child: Child,
        socket: TcpStream,
        next_id: u64,
        _profile: tempfile::TempDir,
    }

    impl Drop for Browser {
        fn drop(&mut self) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }

    /// The body of an HTTP GET (the DevTools server keeps connections open: read
    /// Content-Length bytes).
    fn http_get(port: u16, path: &str) -> String {
        let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        write!(s, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n").unwrap();
        let mut reader = BufReader::new(s);
        let mut length = 0;
        loop {
            let mut line = String::new();
            if reader.read_line(&mut line).unwrap_or(0) == 0 || line == "\r\n" {
                break;
            }
            if let Some((name, value)) = line.split_once(':')
                && name.eq_ignore_ascii_case("content-length")
            {
                length = value.trim().parse().unwrap_or(0);
            }
        }
        let mut body = vec![0u8; length];
        reader.read_exact(&mut body).unwrap();
        String::from_utf8_lossy(&body).into_owned()
    }

    impl Browser {
        /// Starts Chromium on `url` (flags as in `run_chromium`, real time) and connects to the
        /// page.
        pub fn open(browser: &std::path::Path, url: &str, window: (u32, u32)) -> Browser {
            let profile = tempfile::tempdir().unwrap();
            let mut child = Command::new(browser)
                .args(super::CHROMIUM_FLAGS)
                .args(["--remote-debugging-port=0", &format!("--window-size={},{}", window.0, window.1)])
                .arg(format!("--user-data-dir={}", profile.path().display()))
                .arg(url)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            // "DevTools listening on ws://127.0.0.1:PORT/devtools/browser/..."
            let stderr = child.stderr.take().unwrap();
            let (tx, rx) = std::sync::mpsc::channel();
            std::thread::spawn(move || {
                for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                    if let Some(rest) = line.split("ws://127.0.0.1:").nth(1) {
                        let _ = tx.send(rest.split('/').next().unwrap_or_default().parse::<u16>().unwrap_or(0));
                    }
                }
            });
            let port = rx.recv_timeout(Duration::from_secs(30)).expect("chromium prints its DevTools port");
            let started = Instant::now();
            let ws_url = loop {
                let list: serde_json::Value = serde_json::from_str(&http_get(port, "/json/list")).unwrap_or_default();
                let page = list.as_array().and_then(|l| l.iter().find(|t| t["type"] == "page").cloned());
                if let Some(url) = page.and_then(|p| p["webSocketDebuggerUrl"].as_str().map(String::from)) {
                    break url;
                }
                assert!(started.elapsed() < Duration::from_secs(30), "no page target");
                std::thread::sleep(Duration::from_millis(100));
            };
            let path = &ws_url[ws_url.find("/devtools").unwrap()..];
            let mut socket = TcpStream::connect(("127.0.0.1", port)).unwrap();
            socket.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
            write!(
                socket,
                "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
                 Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
            )
            .unwrap();
            let mut head = Vec::new();
            let mut byte = [0u8; 1];
            while !head.ends_with(b"\r\n\r\n") {
                socket.read_exact(&mut byte).unwrap();
                head.push(byte[0]);
            }
            assert!(head.starts_with(b"HTTP/1.1 101"), "{}", String::from_utf8_lossy(&head));
            Browser { child, socket, next_id: 1, _profile: profile }
        }

        fn send_frame(&mut self, payload: &[u8]) {
            let mut frame = vec![0x81u8]; // FIN, text
            let mask = [0x12u8, 0x34, 0x56, 0x78];
            match payload.len() {
                n if n < 126 => frame.push(0x80 | n as u8),
                n if n < 65536 => {
                    frame.push(0x80 | 126);
                    frame.extend((n as u16).to_be_bytes());
                }
                n => {
                    frame.push(0x80 | 127);
                    frame.extend((n as u64).to_be_bytes());
                }
            }
            frame.extend(mask);
            frame.extend(payload.iter().enumerate().map(|(i, b)| b ^ mask[i % 4]));
            self.socket.write_all(&frame).unwrap();
        }

        fn read_message(&mut self) -> String {
            let mut message = Vec::new();
            loop {
                let mut head = [0u8; 2];
                self.socket.read_exact(&mut head).unwrap();
                let mut len = u64::from(head[1] & 0x7f);
                if len == 126 {
                    let mut b = [0u8; 2];
                    self.socket.read_exact(&mut b).unwrap();
                    len = u64::from(u16::from_be_bytes(b));
                } else if len == 127 {
                    let mut b = [0u8; 8];
                    self.socket.read_exact(&mut b).unwrap();
                    len = u64::from_be_bytes(b);
                }
                let mut payload = vec![0u8; len as usize];
                self.socket.read_exact(&mut payload).unwrap();
                message.extend(payload);
                if head[0] & 0x80 != 0 {
                    return String::from_utf8_lossy(&message).into_owned();
                }
            }
        }

        /// Sends a command and returns its `result` (or the error reply), skipping events.
        fn try_call(
            &mut self,
            method: &str,
            params: &serde_json::Value,
        ) -> Result<serde_json::Value, serde_json::Value> {
            let id = self.next_id;
            self.next_id += 1;
            let text = serde_json::json!({ "id": id, "method": method, "params": params }).to_string();
            self.send_frame(text.as_bytes());
            loop {
                let reply: serde_json::Value = serde_json::from_str(&self.read_message()).unwrap();
                if reply["id"] == id {
                    return if reply.get("error").is_some() { Err(reply) } else { Ok(reply["result"].clone()) };
                }
            }
        }

        /// Sends a command and returns its `result`; while the page is still loading (its
        /// script context replaced), tries again for up to 30 s.
        pub fn call(&mut self, method: &str, params: serde_json::Value) -> serde_json::Value {
            let started = Instant::now();
            loop {
                match self.try_call(method, &params) {
                    Ok(result) => return result,
                    Err(reply) if started.elapsed() < Duration::from_secs(30) => {
                        eprintln!("{method}: {reply}, trying again");
                        std::thread::sleep(Duration::from_millis(100));
                    }
                    Err(reply) => panic!("{method}: {reply}"),
                }
            }
        }

        /// Evaluates `expression` in the page (awaiting a promise) and returns its value.
        pub fn eval(&mut self, expression: &str) -> serde_json::Value {
            let r = self.call(
                "Runtime.evaluate",
                serde_json::json!({ "expression": expression, "awaitPromise": true, "returnByValue": true }),
            );
            assert!(r.get("exceptionDetails").is_none(), "{expression}: {r}");
            r["result"]["value"].clone()
        }

        /// Waits (up to 60 s) until the viewer page is ready or reports an error, and returns
        /// `data-ready` or the error. Polls from here: the browser starts on about:blank, and
        /// a script context can vanish under an evaluation while the page replaces it.
        pub fn wait_ready(&mut self) -> String {
            let started = Instant::now();
            let expression = "location.protocol === 'file:' && document.body \
                              ? (document.body.dataset.error || document.body.dataset.ready || '') : ''";
            loop {
                let params = serde_json::json!({ "expression": expression, "returnByValue": true });
                if let Ok(r) = self.try_call("Runtime.evaluate", &params)
                    && let Some(state) = r["result"]["value"].as_str()
                    && !state.is_empty()
                    && state != "0"
                {
                    return state.to_string();
                }
                assert!(started.elapsed() < Duration::from_secs(60), "the page did not get ready in 60 s");
                std::thread::sleep(Duration::from_millis(50));
            }
        }

        /// Presses and releases a key (`key` as in KeyboardEvent.key).
        pub fn key(&mut self, key: &str, code: u32) {
            for kind in ["keyDown", "keyUp"] {
                self.call(
                    "Input.dispatchKeyEvent",
                    serde_json::json!({ "type": kind, "key": key, "code": key, "windowsVirtualKeyCode": code }),
                );
            }
        }

        /// Clicks with the left button at page coordinates.
        pub fn click(&mut self, x: f64, y: f64) {
            for kind in ["mouseMoved", "mousePressed", "mouseReleased"] {
                self.call(
                    "Input.dispatchMouseEvent",
                    serde_json::json!({ "type": kind, "x": x, "y": y, "button": "left", "buttons": if kind == "mousePressed" { 1 } else { 0 }, "clickCount": 1 }),
                );
            }
        }
    }
}

/// What a user does, in a running page (real time, DevTools protocol): the right arrow steps
/// one frame, a click in the middle of the gap chart jumps to the middle of the take, the
/// play button plays it at its frame rate, and hovering over a sphere names its marker.
#[test]
fn page_answers_keys_clicks_and_playback() {
    let Some(data) = shared_data() else { return };
    let Some(browser) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("85_02.html");
    let out = locap().arg("view").arg(data.join("cmu-c3d/85_02.c3d")).arg("-o").arg(&page).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut b = cdp::Browser::open(&browser, &format!("file://{}", page.display()), WINDOW);
    assert_eq!(b.wait_ready(), "1");
    assert_eq!(b.eval("locapViewer.frame"), 0);

    // Hover: the marker under the pointer is named.
    let at = b.eval("locapViewer.screenPosition(20)");
    let name = b.eval("locapViewer.meta.markers[20]").as_str().unwrap().to_string();
    b.call("Input.dispatchMouseEvent", serde_json::json!({ "type": "mouseMoved", "x": at["x"], "y": at["y"] }));
    let tip = b.eval(
        "new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => \
                      r(document.getElementById('tip').hidden ? '' : document.getElementById('tip').textContent))))",
    );
    assert!(tip.as_str().unwrap().starts_with(&name), "hovering marker 20 ({name}) shows {tip}");

    b.key("ArrowRight", 39);
    assert_eq!(b.eval("locapViewer.frame"), 1);
    assert_eq!(b.eval("document.body.dataset.frame"), "1");
    assert_eq!(b.eval("location.hash"), "#frame=1", "the address follows the scrub");

    let frames = b.eval("locapViewer.frames").as_f64().unwrap();
    let rect = b.eval("(() => { const r = document.getElementById('gaps').getBoundingClientRect(); return [r.left, r.top, r.width]; })()");
    let (left, top, width) = (rect[0].as_f64().unwrap(), rect[1].as_f64().unwrap(), rect[2].as_f64().unwrap());
    // The chart's frames run from 96 px (marker names) to 10 px before its right edge.
    b.click(left + 96.0 + (width - 106.0) / 2.0, top + 20.0);
    let middle = b.eval("locapViewer.frame").as_f64().unwrap();
    assert!((middle - frames / 2.0).abs() <= frames * 0.01 + 1.0, "clicked the middle, got frame {middle} of {frames}");

    let rect = b.eval("(() => { const r = document.getElementById('play').getBoundingClientRect(); return [r.left + r.width / 2, r.top + r.height / 2]; })()");
    b.click(rect[0].as_f64().unwrap(), rect[1].as_f64().unwrap());
    assert_eq!(b.eval("locapViewer.playing"), true);
    // Wait (polling, however slow the machine) until playback has run 120 frames, then check
    // the frames follow the page's own animation clock at 120 Hz, 1x: no wall-clock timing of
    // a shared machine from outside.
    let mut played = serde_json::Value::Null;
    for _ in 0..600 {
        played = b.eval("[locapViewer.playedFrames, locapViewer.playedMs, locapViewer.frame]");
        if played[0].as_f64().unwrap() >= 120.0 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let (frames_played, ms) = (played[0].as_f64().unwrap(), played[1].as_f64().unwrap());
    eprintln!("playback: {frames_played} frames in {ms:.0} ms of animation time");
    assert!(frames_played >= 120.0, "playback advanced only {frames_played} frames");
    assert!((frames_played - 120.0 * ms / 1000.0).abs() <= 1.0, "{frames_played} frames in {ms:.0} ms at 120 Hz");
    let expected = (middle + frames_played) % frames;
    assert_eq!(played[2].as_f64().unwrap(), expected, "the frame shown is the frame played to");
}
