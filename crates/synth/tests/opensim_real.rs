//! The OpenSim-built layout against the shared 62-marker takes: the Rajagopal full-body model
//! and `MarkerSet.xml` give one marker per label of `KneeltoProne01.c3d`, on the model's
//! bodies, and the markers of each body sit on the take's subject as a rigid group of the same
//! shape (fitted rigidly, body by body, on the take's first frame).

mod common;

use locap_clean::procrustes::align;
use locap_core::skeleton::forward_kinematics;
use locap_core::{Quat, Vec3};
use locap_synth::opensim::{XmlSource, layout_from_opensim};

fn layout(data: &std::path::Path) -> locap_synth::Layout {
    let model = std::fs::read_to_string(data.join("labeling/Rajagopal2015_mod.osim")).unwrap();
    let markers = std::fs::read_to_string(data.join("labeling/MarkerSet.xml")).unwrap();
    layout_from_opensim(
        XmlSource { name: "Rajagopal2015_mod.osim", text: &model },
        Some(XmlSource { name: "MarkerSet.xml", text: &markers }),
    )
    .unwrap()
}

#[test]
fn the_rajagopal_model_gives_the_62_marker_set_of_the_takes() {
    let Some(data) = common::shared_data() else { return };
    let layout = layout(&data);
    let skeleton_section = layout.skeleton.as_ref().unwrap();
    let skeleton = skeleton_section.to_skeleton().unwrap();
    // 23 bodies besides ground, pelvis first.
    assert_eq!(skeleton.len(), 23);
    assert_eq!(skeleton.joints()[0].name, "pelvis");
    let take = locap_io::c3d::read_path(&data.join("labeling/KneeltoProne01.c3d")).unwrap().to_take().unwrap();
    let labels: Vec<String> = take.markers().iter().map(|m| m.label.clone()).collect();
    let names: Vec<String> = layout.markers.iter().map(|m| m.name.clone()).collect();
    assert_eq!(names.len(), 62);
    assert_eq!(names, labels, "the marker set's order is the take's");
    // Limits: the knee flexes one way only (0..170 degrees in the model).
    let knee = skeleton_section.joints.iter().find(|j| j.name == "tibia_r").unwrap();
    let dofs = knee.dofs.as_ref().unwrap();
    assert_eq!(dofs.len(), 1);
    assert!((dofs[0].max_deg - 170.0).abs() < 0.1 && dofs[0].min_deg == 0.0, "{dofs:?}");
    // Thigh length (hip to knee centre) of the unscaled model: about 40 cm.
    let thigh = Vec3::from(knee.offset_mm).norm();
    assert!((380.0..440.0).contains(&thigh), "thigh {thigh} mm");

    // Each body's markers against the take's first frame, fitted rigidly per body.
    let bound = layout.bind(&skeleton).unwrap();
    let rest = forward_kinematics(&skeleton, &vec![Quat::identity(); skeleton.len()], Vec3::zeros());
    let (mut sum, mut n) = (0.0, 0);
    for j in 0..skeleton.len() {
        let (model, real): (Vec<Vec3>, Vec<Vec3>) = bound
            .markers
            .iter()
            .enumerate()
            .filter(|(_, m)| m.joint == j)
            .filter_map(|(k, m)| Some((m.position_mm(&rest, Vec3::zeros()), take.position_mm(0, k)?)))
            .unzip();
        let Some(fit) = align(&model, &real) else { continue };
        let mut body = 0.0;
        for (a, b) in model.iter().zip(&real) {
            body += (fit.rotation * a + fit.translation - b).norm_squared();
        }
        let rms = (body / model.len() as f64).sqrt();
        eprintln!("{:<10} {} markers: rigid fit RMS {rms:5.1} mm", skeleton.joints()[j].name, model.len());
        // The model is unscaled and the markers are placed by hand: a few centimetres.
        assert!(rms < 40.0, "{}: {rms:.1} mm", skeleton.joints()[j].name);
        sum += body;
        n += model.len();
    }
    let rms = (sum / n as f64).sqrt();
    eprintln!("all bodies with 3+ markers: {n} markers, rigid fit RMS {rms:.1} mm");
    assert!(n >= 50 && rms < 25.0, "{n} markers, {rms:.1} mm");
}

#[test]
fn the_layout_round_trips_through_toml() {
    let Some(data) = common::shared_data() else { return };
    let layout = layout(&data);
    let again = locap_synth::Layout::from_toml(&layout.to_toml()).unwrap();
    assert_eq!(again, layout);
}
