//! Property tests of the C3D writer: any take converted with `C3dFile::from_take`, written and
//! read back gives the same take (validity identical, positions within 1e-3 mm since
//! `from_take` stores f32), and more than 255 markers go through `POINT:LABELS2`.

use locap_core::{MarkerName, Take, UpAxis, Vec3};
use locap_io::c3d::{self, C3dFile};
use proptest::prelude::*;

fn write_read(take: &Take) -> C3dFile {
    let file = C3dFile::from_take(take).unwrap();
    let mut bytes = Vec::new();
    c3d::write(&file, &mut bytes).unwrap();
    c3d::read(&bytes).unwrap()
}

fn assert_same_take(a: &Take, b: &Take) {
    assert_eq!(b.markers(), a.markers());
    assert_eq!(b.frame_count(), a.frame_count());
    assert_eq!(b.validity(), a.validity());
    assert_eq!(b.first_frame, a.first_frame);
    assert_eq!(b.up_axis, a.up_axis);
    assert_eq!(b.frame_rate_hz(), a.frame_rate_hz());
    for f in 0..a.frame_count() {
        for k in 0..a.marker_count() {
            if let (Some(p), Some(q)) = (a.position_mm(f, k), b.position_mm(f, k)) {
                assert!((p - q).amax() <= 1e-3, "frame {f} marker {k}: {p} became {q}");
            }
        }
    }
}

/// A marker name as C3D stores it: no surrounding blanks, optionally `Subject:Label`.
fn marker_name() -> impl Strategy<Value = MarkerName> {
    (proptest::option::of("[A-Z][a-z0-9]{0,7}"), "[A-Za-z*][A-Za-z0-9_]{0,15}")
        .prop_map(|(subject, label)| MarkerName { subject, label })
}

/// 1-20 markers, 1-100 frames, about a fifth of the samples missing, coordinates within
/// +-5000 mm, a frame rate that an f32 holds exactly (`POINT:RATE` is a float).
fn take() -> impl Strategy<Value = Take> {
    (1usize..=20, 1usize..=100)
        .prop_flat_map(|(m, t)| {
            (
                proptest::collection::vec(marker_name(), m),
                proptest::collection::vec(
                    proptest::option::weighted(0.8, proptest::array::uniform3(-5000.0f64..5000.0)),
                    m * t,
                ),
                (1.0f32..2000.0).prop_map(f64::from),
                1u32..=65535,
                any::<bool>(),
            )
        })
        .prop_map(|(markers, samples, rate, first_frame, y_up)| {
            // (0, 0, 0) means missing in C3D (the CMU convention), so it is not a valid sample.
            let samples: Vec<Option<Vec3>> =
                samples.into_iter().map(|s| s.map(Vec3::from).filter(|p| *p != Vec3::zeros())).collect();
            let mut take = Take::from_samples(markers, &samples, rate).unwrap();
            take.first_frame = first_frame;
            take.up_axis = if y_up { UpAxis::Y } else { UpAxis::Z };
            take
        })
}

proptest! {
    #[test]
    fn from_take_write_read_gives_the_take_back(take in take()) {
        let file = write_read(&take);
        assert_same_take(&take, &file.to_take().unwrap());
    }
}

#[test]
fn more_than_255_markers_use_labels2() {
    let m = 300;
    let markers: Vec<MarkerName> =
        (0..m).map(|i| MarkerName { subject: Some("Sub".into()), label: format!("M{i}") }).collect();
    let samples: Vec<Option<Vec3>> =
        (0..3 * m).map(|i| (i % 7 != 0).then(|| Vec3::new(i as f64, -(i as f64), 0.5))).collect();
    let take = Take::from_samples(markers, &samples, 100.0).unwrap();
    let file = write_read(&take);
    assert_eq!(file.point_count, m);
    let labels = file.parameters.get("POINT", "LABELS").unwrap().strings();
    let labels2 = file.parameters.get("POINT", "LABELS2").expect("POINT:LABELS2 written").strings();
    assert_eq!((labels.len(), labels2.len()), (255, m - 255));
    assert_eq!(labels2[0], "Sub:M255");
    assert_same_take(&take, &file.to_take().unwrap());
}
