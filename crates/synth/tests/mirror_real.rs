//! Mirroring real CMU motion (`synthesize::mirror_motion`, `locap synth --mirror`): every joint
//! of the CMU ASF skeleton finds its left/right partner, the mirrored joints lie on the
//! reflected path of their partners, and the built-in 41-marker layout rides the mirrored
//! subject with its left markers on the reflected path of the original's right markers, except
//! the markers Vicon's set staggers between the sides on purpose.

mod common;

use locap_io::asf_amc::{read_amc_path, read_asf_path};
use locap_synth::Layout;
use locap_synth::synthesize::{LabFrame, SynthConfig, Variation, mirror_motion, synthesize};
use rand::SeedableRng;

#[test]
fn cmu_motion_mirrors_onto_the_other_side() {
    let Some(data) = common::shared_data() else { return };
    let asf = read_asf_path(&data.join("cmu-asfamc/03/03.asf")).unwrap();
    let motion = read_amc_path(&data.join("cmu-asfamc/03/03_01.amc"), &asf, 120.0).unwrap();
    // CMU's ASF has its left side at +x of the motion frame.
    let mirrored = mirror_motion(&motion, 0).unwrap();
    let names: Vec<&str> = motion.skeleton.joints().iter().map(|j| j.name.as_str()).collect();
    let partner = |name: &str| {
        let other = match name.chars().next() {
            Some('l') if names.contains(&format!("r{}", &name[1..]).as_str()) => format!("r{}", &name[1..]),
            Some('r') if names.contains(&format!("l{}", &name[1..]).as_str()) => format!("l{}", &name[1..]),
            _ => name.to_string(),
        };
        names.iter().position(|n| *n == other).unwrap()
    };
    let paired = names.iter().filter(|n| partner(n) != names.iter().position(|m| m == *n).unwrap()).count();
    assert!(paired >= 20, "only {paired} joints paired");
    for f in (0..motion.frame_count()).step_by(97) {
        let (a, b) = (motion.forward_kinematics(f), mirrored.forward_kinematics(f));
        for (k, name) in names.iter().enumerate() {
            let mut x = a.positions_mm[partner(name)];
            x.x = -x.x;
            assert!((b.positions_mm[k] - x).norm() < 1e-6, "frame {f}, {name}");
        }
    }
    // The markers: synthesized without variation on both, each left marker of the mirrored
    // take against the reflected right marker of the original.
    let config = SynthConfig { variation: Variation::none(), ..SynthConfig::default() };
    let run = |m| synthesize(m, &Layout::cmu41(), &config, &mut rand::rngs::StdRng::seed_from_u64(1)).unwrap().take;
    let (plain, flipped) = (run(&motion), run(&mirrored));
    let labels: Vec<String> = plain.markers().iter().map(|n| n.label.clone()).collect();
    // Vicon's set staggers the upper-arm, forearm, thigh and shin markers between the sides so
    // that the sides can be told apart; the mirrored subject wears the same layout, so those
    // stay staggered (they are the layout's, not the reflection's) while the others match.
    let staggered = ["UPA", "FRM", "THI", "SHN"];
    let (mut symmetric, mut offset) = (0.0f64, f64::INFINITY);
    let mut pairs = 0;
    for (k, label) in labels.iter().enumerate() {
        let Some(rest) = label.strip_prefix('L') else { continue };
        let Some(r) = labels.iter().position(|l| *l == format!("R{rest}")) else { continue };
        pairs += 1;
        let mut sum = 0.0;
        for f in 0..plain.frame_count() {
            let mut x = LabFrame::ZUpFromYUp.to_motion(plain.position_mm(f, r).unwrap());
            x.x = -x.x;
            sum += (LabFrame::ZUpFromYUp.to_motion(flipped.position_mm(f, k).unwrap()) - x).norm();
        }
        let mean = sum / plain.frame_count() as f64;
        if staggered.contains(&rest) { offset = offset.min(mean) } else { symmetric = symmetric.max(mean) }
    }
    assert_eq!(pairs, 18, "left/right marker pairs of the 41-marker set");
    // A marker on the wrong side would be 150 mm or more away.
    assert!(symmetric < 30.0, "a mirrored left marker is {symmetric:.1} mm from its reflected right partner");
    assert!(offset > 40.0, "a staggered marker lies {offset:.1} mm from its reflected partner: reflected, not worn");
    println!("{pairs} marker pairs: symmetric ones within {symmetric:.1} mm, staggered ones {offset:.1} mm or more");
}
