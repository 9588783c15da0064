//! The CMU body solver's refinement against a network persistently wrong about a hand (issue
//! 17): a subject holds the hands in their own way through a take, which a network trained on
//! a few subjects cannot know but the finger marker shows. The refinement's first pass lets
//! that marker turn the hand (`BODY_HANDS_BIAS_PASS_FACTOR`), so the second pass corrects the
//! network's bias; with the first pass pulling the hands as hard as the second, the marker
//! barely moves them and the calibration files the rest as the marker worn elsewhere.
//!
//! Real motion, CMU subject 02's (whose hands CMU's solutions hold 17-49 degrees further
//! deviated than subject 01's), synthesized through the shipped 41-marker layout; the
//! "network" is the true motion with the right hand turned 30 degrees, every other joint right.

use locap_clean::{CleanConfig, clean};
use locap_core::{Motion, Quat, Vec3};
use locap_nn::kinematic::{BODY_HANDS, CMU_ASF_DOFS, KinematicSolver, acclaim_axis_frame};
use locap_synth::layout::Layout;
use locap_synth::synthesize::{LabFrame, SynthConfig, Variation, synthesize};
use locap_testkit::shared_file;
use rand::SeedableRng;
use rand::rngs::StdRng;

/// CMU subject 02's motion `name` (120 Hz) on its own skeleton; `None` without the shared data.
fn cmu_02(name: &str) -> Option<Motion> {
    let asf = locap_io::asf_amc::read_asf_path(&shared_file("cmu-asfamc/02/02.asf")?).unwrap();
    Some(locap_io::asf_amc::read_amc_path(&shared_file(&format!("cmu-asfamc/02/{name}.amc"))?, &asf, 120.0).unwrap())
}

/// `motion` with `joint` turned by `angle_deg` more about its ASF `rz` axis in every frame.
fn turned(motion: &Motion, joint: &str, angle_deg: f64) -> Motion {
    let j = motion.skeleton.index_of(joint).unwrap();
    let (_, axis, _) = CMU_ASF_DOFS.iter().find(|(name, ..)| *name == joint).unwrap();
    let frame = acclaim_axis_frame(*axis);
    let turn = frame * Quat::from_axis_angle(&Vec3::z_axis(), angle_deg.to_radians()) * frame.inverse();
    let n = motion.frame_count();
    let rotations = (0..n)
        .flat_map(|f| {
            let mut local = motion.local_rotations(f).to_vec();
            local[j] = turn * local[j];
            local
        })
        .collect();
    let roots = (0..n).map(|f| motion.root_position_mm(f)).collect();
    Motion::new(motion.skeleton.clone(), rotations, roots, motion.frame_rate_hz()).unwrap()
}

/// Mean angle (degrees) between `joint`'s local rotations in `a` and `b`.
fn joint_error_deg(a: &Motion, b: &Motion, joint: &str) -> f64 {
    let (i, k) = (a.skeleton.index_of(joint).unwrap(), b.skeleton.index_of(joint).unwrap());
    let n = a.frame_count().min(b.frame_count());
    (0..n).map(|f| a.local_rotations(f)[i].angle_to(&b.local_rotations(f)[k]).to_degrees()).sum::<f64>() / n as f64
}

#[test]
fn the_first_pass_lets_the_finger_marker_correct_a_network_wrong_about_the_hand() {
    let Some(motion) = cmu_02("02_03") else {
        return;
    };
    let config = SynthConfig { lab: LabFrame::ZUpFromYUp, variation: Variation::none(), ..SynthConfig::default() };
    let synth = synthesize(&motion, &Layout::cmu41(), &config, &mut StdRng::seed_from_u64(3)).unwrap();
    let truth = synth.motion;
    let network = turned(&truth, "rhand", 30.0);
    assert!((joint_error_deg(&network, &truth, "rhand") - 30.0).abs() < 0.5);
    let cleaned = clean(&synth.take, &CleanConfig::default());
    let rate_hz = synth.take.frame_rate_hz();

    let solver = KinematicSolver::cmu41().unwrap();
    let (refined, _) = solver.refine(&cleaned, rate_hz, &network).unwrap();
    let full: Vec<(&str, f64)> = BODY_HANDS.iter().map(|j| (*j, 1.0)).collect();
    let held = solver.with_bias_pass_factors(&full).unwrap();
    let (held_refined, _) = held.refine(&cleaned, rate_hz, &network).unwrap();

    let (default_deg, held_deg) =
        (joint_error_deg(&refined, &truth, "rhand"), joint_error_deg(&held_refined, &truth, "rhand"));
    // Measured: 11.5 against 23.5 degrees.
    assert!(default_deg < 15.0, "default: the right hand {default_deg:.1} degrees off (held: {held_deg:.1})");
    assert!(default_deg < 0.65 * held_deg, "default {default_deg:.1} against held {held_deg:.1} degrees");
    // The left hand, where the network was right, stays right.
    let left = joint_error_deg(&refined, &truth, "lhand");
    assert!(left < 5.0, "the left hand {left:.1} degrees off");
}
