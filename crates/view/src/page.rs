//! The viewer page: one HTML file with three.js, the viewer script and the take's data.
//!
//! The page needs no network: [three.js](https://threejs.org) (r170, MIT, vendored in
//! `assets/` with its licence, see `assets/VENDORED.md`) travels inside it as text and is
//! imported from a `blob:` URL; the data are base64 blocks described by a JSON header (see
//! [`crate::encode`] for the block format). Everything is converted to the viewer's axes
//! (three.js: Y up, millimetres) here, so the script knows nothing of C3D axes.
//!
//! For tests and scripts the page reports its state on `<body>` as data attributes
//! (`data-ready`, `data-error` if it cannot show the take, `data-frame`, `data-spheres`
//! (markers drawn), `data-ghosts` (missing markers drawn where last seen), `data-visible`,
//! `data-filled`, `data-outlier`, `data-missing` (counts at the frame), `data-joints`,
//! `data-compared`, `data-error-mm`, `data-load-ms`) and in `window.locapViewer` (the same
//! values, `timings` of the loading steps, and `setFrame(n)`, `play()`, `pause()`,
//! `screenPosition(marker)`); `#frame=N` in the URL (0-based frame index) opens or moves it
//! to a frame, `&play=1` starts playback, `&theta=`, `&phi=`, `&radius=` (radians, metres)
//! place the camera.

use crate::ViewError;
use crate::encode::{self, Quantiser};
use crate::states::SampleState;
use locap_core::{Motion, Take, UpAxis, Vec3};
use serde::Serialize;

const TEMPLATE: &str = include_str!("../assets/viewer.html");
const VIEWER_JS: &str = include_str!("../assets/viewer.js");
const THREE_JS: &str = include_str!("../assets/three.module.min.js");

/// Everything one page shows.
#[derive(Debug, Clone)]
pub struct ViewInput<'a> {
    /// Title shown in the page (usually the file name).
    pub title: String,
    /// The take.
    pub take: &'a Take,
    /// State of each sample of `take`, frame-major (see [`crate::states::sample_states`]).
    pub states: &'a [SampleState],
    /// A solved skeleton motion to overlay, with the axis that is up in it (BVH: Y).
    pub motion: Option<(&'a Motion, UpAxis)>,
    /// A second take to overlay (e.g. ground truth), with its title. Markers are matched by
    /// name; the page shows the mean distance per frame.
    pub compare: Option<(&'a Take, String)>,
    /// Marker pairs (indices into `take`'s markers) joined by an edge, e.g. each marker with
    /// its most stable neighbours (LocalMoCap section 3, `locap_clean::neighbours::stable_edges`);
    /// empty for none. The page has a switch to hide them.
    pub edges: &'a [[usize; 2]],
}

#[derive(Serialize)]
struct Meta {
    format: u32,
    generator: String,
    title: String,
    frames: usize,
    first_frame: u32,
    rate_hz: f64,
    markers: Vec<String>,
    quant: Quantiser,
    delta_order: usize,
    blocks: Vec<BlockInfo>,
    edges: Vec<[usize; 2]>,
    state_names: Vec<&'static str>,
    state_counts: [usize; 4],
    skeleton: Option<SkeletonMeta>,
    compare: Option<CompareMeta>,
}

#[derive(Serialize)]
struct BlockInfo {
    name: &'static str,
    dtype: &'static str,
    len: usize,
}

#[derive(Serialize)]
struct SkeletonMeta {
    joints: Vec<String>,
    parents: Vec<i64>,
}

#[derive(Serialize)]
struct CompareMeta {
    title: String,
    matched_markers: usize,
    mean_error_mm: Option<f64>,
}

/// Version of the page's data format (the `format` field of its JSON header).
pub const FORMAT_VERSION: u32 = 1;

/// The position of `p` (in a take or motion whose vertical axis is `up`) in the viewer's
/// axes: three.js is Y-up and right-handed, so a Z-up `(x, y, z)` becomes `(y, z, x)`, the lab
/// convention of [`locap_core::units::z_up_to_y_up`] (the one under which CMU's AMC motions,
/// Y-up, land on the markers of their Z-up C3D takes, so solved BVH motions overlay
/// correctly).
pub fn to_view_axes(p: Vec3, up: UpAxis) -> Vec3 {
    up.to_y_up(p)
}

/// Per frame, the mean distance in mm between the markers of `take` and the same-named
/// markers of `other`, over markers present in both at that frame (`None` where there are
/// none). Also returns how many markers matched by name.
///
/// # Errors
/// The takes have different frame counts.
pub fn per_frame_error_mm(take: &Take, other: &Take) -> Result<(Vec<Option<f64>>, usize), ViewError> {
    if other.frame_count() != take.frame_count() {
        return Err(ViewError::FrameCountMismatch {
            what: "the --compare take",
            expected: take.frame_count(),
            found: other.frame_count(),
        });
    }
    let pairs: Vec<(usize, usize)> = take
        .markers()
        .iter()
        .enumerate()
        .filter_map(|(i, name)| other.marker_index(&name.full()).map(|j| (i, j)))
        .collect();
    let errors = (0..take.frame_count())
        .map(|f| {
            let d: Vec<f64> = pairs
                .iter()
                .filter_map(|&(i, j)| Some((take.position_mm(f, i)? - other.position_mm(f, j)?).norm()))
                .collect();
            (!d.is_empty()).then(|| d.iter().sum::<f64>() / d.len() as f64)
        })
        .collect();
    Ok((errors, pairs.len()))
}

/// Builds the page.
///
/// # Errors
/// `states` does not have one entry per sample, an edge names a marker the take does not
/// have, or the motion or the compared take has a different frame count (or the motion a
/// different frame rate) than the take.
pub fn render(input: &ViewInput<'_>) -> Result<String, ViewError> {
    let take = input.take;
    let (frames, m) = (take.frame_count(), take.marker_count());
    if input.states.len() != frames * m {
        return Err(ViewError::StateCount { expected: frames * m, found: input.states.len() });
    }
    if let Some(edge) = input.edges.iter().find(|e| e.iter().any(|&k| k >= m)) {
        return Err(ViewError::BadEdge { edge: *edge, markers: m });
    }
    let up = take.up_axis;
    let marker_tracks: Vec<Vec<Option<Vec3>>> =
        (0..m).map(|k| take.trajectory_mm(k).into_iter().map(|p| p.map(|p| to_view_axes(p, up))).collect()).collect();

    let joint_tracks: Option<(Vec<Vec<Option<Vec3>>>, SkeletonMeta)> = match input.motion {
        None => None,
        Some((motion, motion_up)) => {
            if motion.frame_count() != frames {
                return Err(ViewError::FrameCountMismatch {
                    what: "the --motion file",
                    expected: frames,
                    found: motion.frame_count(),
                });
            }
            if (motion.frame_rate_hz() - take.frame_rate_hz()).abs() > 1e-3 * take.frame_rate_hz() {
                return Err(ViewError::RateMismatch {
                    take_hz: take.frame_rate_hz(),
                    motion_hz: motion.frame_rate_hz(),
                });
            }
            let joints = motion.skeleton.len();
            let mut tracks = vec![Vec::with_capacity(frames); joints];
            for f in 0..frames {
                for (track, p) in tracks.iter_mut().zip(motion.forward_kinematics(f).positions_mm) {
                    track.push(Some(to_view_axes(p, motion_up)));
                }
            }
            let skeleton = &motion.skeleton;
            let meta = SkeletonMeta {
                joints: skeleton.joints().iter().map(|j| j.name.clone()).collect(),
                parents: skeleton.joints().iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect(),
            };
            Some((tracks, meta))
        }
    };

    let compare = match &input.compare {
        None => None,
        Some((other, title)) => {
            let (errors, matched) = per_frame_error_mm(take, other)?;
            let other_up = other.up_axis;
            let tracks: Vec<Vec<Option<Vec3>>> = take
                .markers()
                .iter()
                .map(|name| match other.marker_index(&name.full()) {
                    Some(j) => {
                        other.trajectory_mm(j).into_iter().map(|p| p.map(|p| to_view_axes(p, other_up))).collect()
                    }
                    None => vec![None; frames],
                })
                .collect();
            let scored: Vec<f64> = errors.iter().flatten().copied().collect();
            let mean = (!scored.is_empty()).then(|| scored.iter().sum::<f64>() / scored.len() as f64);
            Some((tracks, errors, CompareMeta { title: title.clone(), matched_markers: matched, mean_error_mm: mean }))
        }
    };

    // One quantiser for everything drawn, so the script dequantises all blocks alike.
    let all_points = marker_tracks
        .iter()
        .chain(joint_tracks.iter().flat_map(|(t, _)| t))
        .chain(compare.iter().flat_map(|(t, _, _)| t))
        .flat_map(|t| t.iter().flatten().copied());
    let quant = Quantiser::covering(all_points);

    let mut blocks: Vec<(BlockInfo, String)> = Vec::new();
    let mut add = |name: &'static str, dtype: &'static str, len: usize, bytes: Vec<u8>| {
        blocks.push((BlockInfo { name, dtype, len }, encode::pack(&bytes)));
    };
    let positions = encode::encode_tracks(&marker_tracks, &quant);
    add("positions", "i16", positions.len(), encode::i16_bytes(&positions));
    // States marker-major like the positions: one marker's timeline is contiguous.
    let states: Vec<u8> = (0..m).flat_map(|k| (0..frames).map(move |f| input.states[f * m + k] as u8)).collect();
    add("states", "u8", states.len(), states);
    if let Some((tracks, _)) = &joint_tracks {
        let joints = encode::encode_tracks(tracks, &quant);
        add("joints", "i16", joints.len(), encode::i16_bytes(&joints));
    }
    if let Some((tracks, errors, _)) = &compare {
        let positions = encode::encode_tracks(tracks, &quant);
        add("compare", "i16", positions.len(), encode::i16_bytes(&positions));
        let valid: Vec<u8> = tracks
            .iter()
            .flat_map(|t| t.iter().map(|p| if p.is_some() { SampleState::Visible } else { SampleState::Missing } as u8))
            .collect();
        add("compare_states", "u8", valid.len(), valid);
        let errors: Vec<f32> = errors.iter().map(|e| e.map_or(f32::NAN, |e| e as f32)).collect();
        add("error", "f32", errors.len(), encode::f32_bytes(&errors));
    }

    let mut state_counts = [0usize; 4];
    for s in input.states {
        state_counts[*s as usize] += 1;
    }
    let meta = Meta {
        format: FORMAT_VERSION,
        generator: format!("locap {}", env!("CARGO_PKG_VERSION")),
        title: input.title.clone(),
        frames,
        first_frame: take.first_frame,
        rate_hz: take.frame_rate_hz(),
        markers: take.markers().iter().map(|n| n.full()).collect(),
        quant,
        delta_order: encode::DELTA_ORDER,
        blocks: blocks
            .iter()
            .map(|(info, _)| BlockInfo { name: info.name, dtype: info.dtype, len: info.len })
            .collect(),
        edges: input.edges.to_vec(),
        state_names: SampleState::ALL.iter().map(|s| s.name()).collect(),
        state_counts,
        skeleton: joint_tracks.map(|(_, meta)| meta),
        compare: compare.map(|(_, _, meta)| meta),
    };
    // `</script` or `<!--` inside a <script> element would end or confuse it; `\u003c` is the
    // same JSON string.
    let meta_json =
        serde_json::to_string(&meta).map_err(|e| ViewError::BadBlock(e.to_string()))?.replace('<', "\\u003c");

    let data_len: usize = blocks.iter().map(|(_, text)| text.len() + 80).sum();
    let mut data = String::with_capacity(data_len);
    for (info, text) in &blocks {
        data.push_str(&format!("<script type=\"application/octet-stream\" id=\"locap-block-{}\">", info.name));
        data.push_str(text);
        data.push_str("</script>\n");
    }
    fill_template(&[
        ("{{TITLE}}", &html_escape(&input.title)),
        ("{{META}}", &meta_json),
        ("{{DATA}}", &data),
        ("{{THREE}}", THREE_JS),
        ("{{VIEWER}}", VIEWER_JS),
    ])
}

/// Replaces each placeholder of the template once, in one pass (the data are megabytes).
fn fill_template(values: &[(&str, &str)]) -> Result<String, ViewError> {
    let mut out = String::with_capacity(TEMPLATE.len() + values.iter().map(|(_, v)| v.len()).sum::<usize>());
    let mut rest = TEMPLATE;
    while let Some(start) = rest.find("{{") {
        let end =
            rest[start..].find("}}").map(|e| start + e + 2).ok_or_else(|| ViewError::BadBlock("template".into()))?;
        let key = &rest[start..end];
        let value =
            values.iter().find(|(k, _)| *k == key).ok_or_else(|| ViewError::BadBlock(format!("template key {key}")))?;
        out.push_str(&rest[..start]);
        out.push_str(value.1);
        rest = &rest[end..];
    }
    out.push_str(rest);
    Ok(out)
}

fn html_escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The JSON header and the decoded blocks of a page made by [`render`]; the same parsing the
/// page's script does, for tests and tools.
#[derive(Debug)]
pub struct ParsedPage {
    /// The JSON header.
    pub meta: serde_json::Value,
    /// Each block's name and bytes, after base64 and zlib.
    pub blocks: Vec<(String, Vec<u8>)>,
}

impl ParsedPage {
    /// Parses a page written by [`render`].
    ///
    /// # Errors
    /// The page was not written by [`render`] or is damaged.
    pub fn parse(html: &str) -> Result<ParsedPage, ViewError> {
        let between = |start: &str, from: usize| -> Option<(usize, usize)> {
            let s = html[from..].find(start)? + from + start.len();
            let e = html[s..].find("</script>")? + s;
            Some((s, e))
        };
        let (s, e) = between("<script type=\"application/json\" id=\"locap-meta\">", 0)
            .ok_or_else(|| ViewError::BadBlock("no locap-meta header".into()))?;
        let meta: serde_json::Value =
            serde_json::from_str(&html[s..e]).map_err(|e| ViewError::BadBlock(format!("header: {e}")))?;
        let mut blocks = Vec::new();
        for info in meta["blocks"].as_array().cloned().unwrap_or_default() {
            let name = info["name"].as_str().unwrap_or_default().to_string();
            let tag = format!("<script type=\"application/octet-stream\" id=\"locap-block-{name}\">");
            let (s, e) = between(&tag, 0).ok_or_else(|| ViewError::BadBlock(format!("no block {name}")))?;
            blocks.push((name, encode::unpack(&html[s..e])?));
        }
        Ok(ParsedPage { meta, blocks })
    }

    /// The bytes of block `name`.
    pub fn block(&self, name: &str) -> Option<&[u8]> {
        self.blocks.iter().find(|(n, _)| n == name).map(|(_, b)| b.as_slice())
    }

    /// The quantiser of the header.
    pub fn quantiser(&self) -> Option<Quantiser> {
        let axes = |key: &str| -> Option<[f64; 3]> {
            let v = self.meta["quant"][key].as_array()?;
            Some([v.first()?.as_f64()?, v.get(1)?.as_f64()?, v.get(2)?.as_f64()?])
        };
        Some(Quantiser { offset_mm: axes("offset_mm")?, step_mm: axes("step_mm")? })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::states::sample_states;
    use locap_core::{EulerOrder, Joint, MarkerName, Quat, Skeleton};

    fn take(frames: usize) -> Take {
        let markers = ["LFHD", "RFHD", "C7"].iter().map(|n| MarkerName::parse(n)).collect();
        let samples: Vec<Option<Vec3>> = (0..frames * 3)
            .map(|i| {
                let (f, k) = ((i / 3) as f64, (i % 3) as f64);
                (i != 7).then(|| Vec3::new(100.0 * k + f, -50.0 * k, 1500.0 + 10.0 * k + 0.5 * f))
            })
            .collect();
        Take::from_samples(markers, &samples, 120.0).unwrap()
    }

    fn motion(frames: usize) -> Motion {
        let joint = |name: &str, parent, y| Joint {
            name: name.into(),
            parent,
            offset_mm: Vec3::new(0.0, y, 0.0),
            rotation_order: EulerOrder::ZXY,
            is_end_site: false,
        };
        let skeleton = Skeleton::new(vec![joint("Hips", None, 0.0), joint("Spine", Some(0), 300.0)]).unwrap();
        let rotations = vec![Quat::identity(); frames * 2];
        let root: Vec<Vec3> = (0..frames).map(|f| Vec3::new(f as f64, 1000.0, 0.0)).collect();
        Motion::new(skeleton, rotations, root, 120.0).unwrap()
    }

    #[test]
    fn page_carries_the_take_and_decodes_back() {
        let t = take(20);
        let filled = vec!["RFHD 3-5".to_string()];
        let record =
            locap_core::Provenance::from_parameters(&t, |n| if n == "FILLED" { filled.clone() } else { Vec::new() });
        let states = sample_states(&t, &record.unwrap());
        let m = motion(20);
        let input = ViewInput {
            title: "a <take>".into(),
            take: &t,
            states: &states,
            motion: Some((&m, UpAxis::Y)),
            compare: Some((&t, "same".into())),
            edges: &[[0, 1], [1, 2]],
        };
        let html = render(&input).unwrap();
        assert!(html.contains("<title>a &lt;take&gt;"), "title is escaped");
        for key in ["{{TITLE}}", "{{META}}", "{{DATA}}", "{{THREE}}", "{{VIEWER}}"] {
            assert!(!html.contains(key), "{key} is filled");
        }
        let page = ParsedPage::parse(&html).unwrap();
        assert_eq!(page.meta["frames"], 20);
        assert_eq!(page.meta["markers"][2], "C7");
        assert_eq!(page.meta["skeleton"]["parents"], serde_json::json!([-1, 0]));
        assert_eq!(page.meta["compare"]["matched_markers"], 3);
        assert_eq!(page.meta["compare"]["mean_error_mm"], 0.0);
        // Marker-major states: RFHD (marker 1) filled at frames 2..=4 (C3D 3-5, first frame 1),
        // except frame 2, where it has no position (sample 7 = frame 2, marker 1).
        let s = page.block("states").unwrap();
        assert_eq!(&s[20..28], &[0, 0, 3, 1, 1, 0, 0, 0]);
        assert!(s[..20].iter().chain(&s[40..]).all(|x| *x == 0));
        // Positions come back in view axes (Z-up take: (x, y, z) -> (y, z, x)).
        let q = page.quantiser().unwrap();
        let raw: Vec<i16> =
            page.block("positions").unwrap().chunks_exact(2).map(|b| i16::from_le_bytes([b[0], b[1]])).collect();
        let back = encode::decode_tracks(&raw, 3, 20, &q);
        let expect = to_view_axes(t.position_mm(5, 1).unwrap(), UpAxis::Z);
        assert!((back[1][5] - expect).amax() <= q.max_error_mm() + 1e-9);
        // The skeleton: Spine is 300 mm above Hips.
        let joints: Vec<i16> =
            page.block("joints").unwrap().chunks_exact(2).map(|b| i16::from_le_bytes([b[0], b[1]])).collect();
        let j = encode::decode_tracks(&joints, 2, 20, &q);
        assert!((j[1][4] - Vec3::new(4.0, 1300.0, 0.0)).amax() <= q.max_error_mm() + 1e-9);
        let errors: Vec<f32> = page
            .block("error")
            .unwrap()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert_eq!(errors.len(), 20);
        assert!(errors.iter().all(|e| *e == 0.0));
        assert_eq!(page.meta["edges"], serde_json::json!([[0, 1], [1, 2]]));
    }

    #[test]
    fn mismatched_motion_and_compare_are_clear_errors() {
        let t = take(20);
        let states = sample_states(&t, &locap_core::Provenance::default());
        let short = motion(19);
        let base = ViewInput { title: "t".into(), take: &t, states: &states, motion: None, compare: None, edges: &[] };
        let err = render(&ViewInput { motion: Some((&short, UpAxis::Y)), ..base.clone() }).unwrap_err().to_string();
        assert!(err.contains("--motion file has 19 frames, but the take has 20"), "{err}");
        let other = take(21);
        let err = render(&ViewInput { compare: Some((&other, "o".into())), ..base.clone() }).unwrap_err().to_string();
        assert!(err.contains("--compare take has 21 frames"), "{err}");
        let err = render(&ViewInput { edges: &[[0, 3]], ..base.clone() }).unwrap_err().to_string();
        assert!(err.contains("marker 3") && err.contains("3 markers"), "{err}");
        let err = render(&ViewInput { states: &states[1..], ..base }).unwrap_err().to_string();
        assert!(err.contains("sample states"), "{err}");
    }

    #[test]
    fn empty_takes_still_make_a_page() {
        for t in [Take::empty(vec![], 10, 100.0).unwrap(), Take::empty(vec![MarkerName::parse("A")], 0, 100.0).unwrap()]
        {
            let states = sample_states(&t, &locap_core::Provenance::default());
            let input =
                ViewInput { title: "e".into(), take: &t, states: &states, motion: None, compare: None, edges: &[] };
            let page = ParsedPage::parse(&render(&input).unwrap()).unwrap();
            assert_eq!(page.block("positions").unwrap().len(), 0);
            assert_eq!(page.meta["edges"].as_array().unwrap().len(), 0);
        }
    }

    #[test]
    fn per_frame_error_matches_markers_by_name() {
        let a = take(4);
        let mut b = take(4);
        b.set_position_mm(1, 0, Some(a.position_mm(1, 0).unwrap() + Vec3::new(3.0, 4.0, 0.0))).unwrap();
        let (errors, matched) = per_frame_error_mm(&a, &b).unwrap();
        assert_eq!(matched, 3);
        assert_eq!(errors[0], Some(0.0));
        assert!((errors[1].unwrap() - 5.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn assets_cannot_break_out_of_their_script_elements() {
        for (name, text) in [("three.js", THREE_JS), ("viewer.js", VIEWER_JS)] {
            assert!(!text.to_ascii_lowercase().contains("</script"), "{name} contains </script");
        }
    }
}
