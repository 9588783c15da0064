//! `locap convert a.c3d b.c3d` (`c3d::read_path` then `c3d::write_path`) on every real C3D file
//! under `../shared/data` changes nothing beyond what the writer must: the data start, the
//! point bookkeeping (`POINT:USED`, `FRAMES`, `SCALE`, `DATA_START`) and, for non-Intel files,
//! the number format. Each fix of issue 14's round-trip list has its own test on the file
//! that showed it. ezc3d's view of the same round trip is checked by `c3d_ezc3d.rs`.

mod common;

use locap_io::c3d::{self, C3dFile, ParamData, Processor, Record};
use std::path::{Path, PathBuf};

fn data() -> Option<PathBuf> {
    common::shared_data()
}

/// The file as read, and as read back after writing it.
fn round_trip(path: &Path) -> (C3dFile, C3dFile) {
    let before = c3d::read_path(path).unwrap();
    let out = tempfile::tempdir().unwrap();
    let written = out.path().join("out.c3d");
    c3d::write_path(&before, &written).unwrap();
    let after = c3d::read_path(&written).unwrap();
    (before, after)
}

/// Parameters the writer keeps up to date (they describe the data it writes).
fn bookkeeping(r: &Record, params: &c3d::Parameters) -> bool {
    let Record::Parameter(p) = r else { return false };
    let group = params.groups().find(|g| g.id == p.group_id).map(|g| g.name.as_str()).unwrap_or("");
    p.name == "DATA_START"
        || (group == "POINT" && ["USED", "FRAMES", "SCALE", "LONG_FRAMES"].contains(&p.name.as_str()))
        || (group == "TRIAL" && p.name.starts_with("ACTUAL_"))
}

fn records(file: &C3dFile) -> Vec<&Record> {
    file.parameters.records.iter().filter(|r| !bookkeeping(r, &file.parameters)).collect()
}

fn param<'a>(file: &'a C3dFile, group: &str, name: &str) -> &'a ParamData {
    &file.parameters.get(group, name).unwrap_or_else(|| panic!("{group}:{name}")).data
}

/// Event times of all 18 header slots, decoded with the file's processor.
fn event_times(file: &C3dFile) -> Vec<f32> {
    let h = &file.header.raw;
    (0..18)
        .map(|i| {
            let at = 2 * (153 + 2 * i - 1);
            file.processor.f32([h[at], h[at + 1], h[at + 2], h[at + 3]])
        })
        .collect()
}

fn find(name: &str) -> Option<PathBuf> {
    let data = data()?;
    let path = common::files_with_extension(&data, "c3d").into_iter().find(|p| p.ends_with(name));
    Some(path.unwrap_or_else(|| panic!("{name} not found under {}", data.display())))
}

#[test]
fn convert_changes_nothing_beyond_the_bookkeeping() {
    let Some(data) = data() else { return };
    let mut checked = 0;
    for path in common::files_with_extension(&data, "c3d") {
        let Ok(before) = c3d::read_path(&path) else { continue };
        let (_, after) = round_trip(&path);
        let at = path.display();
        // Parameters the writer does not own: the same records in the same order. Absent
        // analog scales and offsets are added (ezc3d crashes without them), nothing else.
        let mut added: Vec<&Record> = records(&after);
        for r in records(&before) {
            let i = added.iter().position(|a| *a == r).unwrap_or_else(|| panic!("{at}: {r:?} changed or lost"));
            added.remove(i);
        }
        for r in added {
            // c3d.org's phasespace_sample.c3d has no parameters: the points need a POINT group.
            if let Record::Group(g) = r
                && g.name == "POINT"
                && before.parameters.group_id("POINT").is_none()
            {
                continue;
            }
            let Record::Parameter(p) = r else { panic!("{at}: group {r:?} added") };
            assert!(["GEN_SCALE", "SCALE", "OFFSET"].contains(&p.name.as_str()), "{at}: {} added", p.name);
        }
        // The writer's own parameters, when the reader found the file consistent.
        if before.warnings.is_empty() {
            for r in before.parameters.records.iter().filter(|r| bookkeeping(r, &before.parameters)) {
                let Record::Parameter(p) = r else { continue };
                // A count the file contradicts itself on (Dance.c3d: POINT:FRAMES 500, header
                // and data 499) is rewritten to the data's.
                let expected = match p.name.as_str() {
                    "FRAMES" => Some(before.frames.min(65535)),
                    "USED" => Some(before.point_count),
                    _ => None,
                };
                let contradicted = expected.is_some_and(|e| p.as_i64().map(|v| v as u16 as usize) != Some(e));
                if p.name != "DATA_START" && !contradicted {
                    let group = before.parameters.groups().find(|g| g.id == p.group_id).unwrap().name.clone();
                    let q = after.parameters.get(&group, &p.name).unwrap();
                    // An integer file can become float (a coordinate past 16 bits): the sign of
                    // POINT:SCALE says so.
                    let same = q.data == p.data || (p.name == "SCALE" && after.storage != before.storage);
                    assert!(same, "{at}: {group}:{} {:?} -> {:?}", p.name, p.data, q.data);
                }
            }
        }
        assert_eq!(before.frames, after.frames, "{at}");
        let bits = |f: &C3dFile| f.points.iter().flat_map(|w| w.map(f32::to_bits)).collect::<Vec<_>>();
        assert!(bits(&before) == bits(&after), "{at}: point words differ");
        if before.storage == after.storage {
            assert_eq!(before.analog, after.analog, "{at}");
        }
        assert_eq!(before.header.events, after.header.events, "{at}");
        assert_eq!(before.header.events_key, after.header.events_key, "{at}");
        // All 18 event slots, used or not: times, display flags, labels.
        let times = |f: &C3dFile| event_times(f).iter().map(|t| t.to_bits()).collect::<Vec<_>>();
        assert_eq!(times(&before), times(&after), "{at}: event times");
        assert_eq!(before.header.raw[376..394], after.header.raw[376..394], "{at}: event display flags");
        assert_eq!(before.header.raw[396..468], after.header.raw[396..468], "{at}: event labels");
        assert_eq!(before.extra_sections, after.extra_sections, "{at}");
        checked += 1;
    }
    assert!(checked > 100, "expected the shared C3D files, checked {checked}");
}

#[test]
fn negative_residual_words_other_than_minus_one_are_kept() {
    // BTK rewrote this file with invalid samples' residual word -32768.
    let Some(path) = find("btk/ADemo1_rewrite_c3d_pc_integer.c3d") else { return };
    let (before, after) = round_trip(&path);
    let count = |f: &C3dFile| f.points.iter().filter(|w| w[3] == -32768.0).count();
    assert!(count(&before) > 0);
    assert_eq!(count(&before), count(&after));
}

#[test]
fn unused_event_slots_of_dec_files_keep_their_labels() {
    // The DEC header has blank (space) labels in its unused event slots.
    for name in ["sample_02/dec_int.c3d", "sample_02/dec_real.c3d"] {
        let Some(path) = find(name) else { return };
        let (before, after) = round_trip(&path);
        assert_eq!(before.processor, Processor::Dec);
        let unused = 396 + 4 * before.header.events.len()..468;
        assert!(before.header.raw[unused.clone()].contains(&b' '), "{name}");
        assert_eq!(before.header.raw[unused.clone()], after.header.raw[unused], "{name}");
        assert_eq!(event_times(&before), event_times(&after), "{name}");
    }
}

#[test]
fn parameters_of_undeclared_groups_stay_undeclared() {
    // c3d.org's TYPE-2/TYPE-4 have parameters of group 7 but no group 7 record.
    for name in ["sample_10/TYPE-2.C3D", "sample_10/TYPE-4.C3D"] {
        let Some(path) = find(name) else { return };
        let (before, after) = round_trip(&path);
        for file in [&before, &after] {
            assert!(file.parameters.groups().all(|g| g.id != 7), "{name}: a group 7 appeared");
            assert!(file.parameters.records.iter().any(|r| matches!(r, Record::Parameter(p) if p.group_id == 7)));
        }
        assert_eq!(records(&before), records(&after), "{name}");
    }
}

#[test]
fn analog_only_files_keep_point_scale() {
    // Kistler: POINT:SCALE -1 with integer analog data; BTK's EMG file: no POINT:SCALE (ezc3d
    // shows its default, -1). Without points it describes nothing and is left as it is.
    for name in ["btk/1123x01EMG.c3d", "c3d-vendors/Kistler.c3d"] {
        let Some(path) = find(name) else { return };
        let (before, after) = round_trip(&path);
        assert_eq!(before.point_count, 0, "{name}");
        let scale = |f: &C3dFile| f.parameters.get("POINT", "SCALE").map(|p| p.data.clone());
        assert_eq!(scale(&before), scale(&after), "{name}");
        assert_eq!((before.storage, &before.analog), (after.storage, &after.analog), "{name}");
        assert_eq!(before.header.scale, after.header.scale, "{name}");
    }
}

#[test]
fn float_analog_offsets_are_carried_as_floats() {
    // The manual says integers; these files store floats (and ezc3d rejects them as read).
    for name in ["sample_13/Dance.c3d", "sample_13/golfswing.c3d"] {
        let Some(path) = find(name) else { return };
        let (before, after) = round_trip(&path);
        assert!(matches!(param(&before, "ANALOG", "OFFSET"), ParamData::Float(_)), "{name}");
        assert_eq!(param(&before, "ANALOG", "OFFSET"), param(&after, "ANALOG", "OFFSET"), "{name}");
    }
}
