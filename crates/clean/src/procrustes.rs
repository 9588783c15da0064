//! Rigid alignment of corresponding point sets (orthogonal Procrustes, Kabsch's SVD solution).
//!
//! Used twice in cleaning: EDM aligns its MDS embedding onto the visible neighbours (paper
//! section 3.1, "Rotation Orthogonal Procrustes Problem", closed form by SVD), and the rigid
//! baseline carries a marker along with three neighbours. nalgebra provides the SVD; the
//! few lines around it are ours because no crate offers the reflection handling both uses
//! need.

use locap_core::Vec3;
use nalgebra::{Matrix3, Rotation3};

/// A rigid motion `p -> rotation * p + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidTransform {
    /// Proper rotation (determinant +1).
    pub rotation: Rotation3<f64>,
    /// Translation, in the target's unit.
    pub translation: Vec3,
}

impl RigidTransform {
    /// Applies the transform to a point.
    pub fn apply(&self, p: &Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// Applies the inverse transform to a point: where `p` came from (`apply(apply_inverse(p))
    /// == p`).
    pub fn apply_inverse(&self, p: &Vec3) -> Vec3 {
        self.rotation.inverse() * (p - self.translation)
    }
}

/// The proper rigid motion that best maps `source[k]` onto `target[k]` in the least-squares
/// sense. A reflection is never returned: when the best orthogonal map is a reflection (the
/// "reflection check"), the smallest singular direction is flipped, which gives the best
/// proper rotation (Kabsch). Returns `None` for fewer than 3 points, mismatched lengths, or a
/// degenerate (collinear) configuration.
pub fn align(source: &[Vec3], target: &[Vec3]) -> Option<RigidTransform> {
    align_weighted(source, target, &vec![1.0; source.len()])
}

/// [`align`] with a non-negative weight per point pair (weighted least squares): points that
/// are known to move less reliably with the others count less.
pub fn align_weighted(source: &[Vec3], target: &[Vec3], weights: &[f64]) -> Option<RigidTransform> {
    let kabsch = Kabsch::new(source, target, weights)?;
    kabsch.proper(kabsch.u, kabsch.source_centre)
}

/// [`align_weighted`] of `source` and of its mirror image `(x, y, -z)` at once, in that order:
/// EDM's MDS embedding is fixed only up to a mirror image and aligns both. One SVD serves
/// both, since mirroring the source by `M = diag(1, 1, -1)` turns the cross-covariance `H`
/// into `M H`, whose SVD is `(M U) S V^T`. `None` where [`align_weighted`] gives `None` (the
/// checks do not depend on the mirror).
pub fn align_weighted_and_mirrored(source: &[Vec3], target: &[Vec3], weights: &[f64]) -> Option<[RigidTransform; 2]> {
    let kabsch = Kabsch::new(source, target, weights)?;
    let mirror = Matrix3::from_diagonal(&Vec3::new(1.0, 1.0, -1.0));
    Some([
        kabsch.proper(kabsch.u, kabsch.source_centre)?,
        kabsch.proper(mirror * kabsch.u, mirror * kabsch.source_centre)?,
    ])
}

/// The weighted centroids and the SVD `H = U S V^T` of the cross-covariance of two point sets.
struct Kabsch {
    source_centre: Vec3,
    target_centre: Vec3,
    u: Matrix3<f64>,
    v: Matrix3<f64>,
}

impl Kabsch {
    fn new(source: &[Vec3], target: &[Vec3], weights: &[f64]) -> Option<Kabsch> {
        if source.len() != target.len() || source.len() != weights.len() || source.len() < 3 {
            return None;
        }
        let total: f64 = weights.iter().sum();
        if !(total > 0.0) || weights.iter().any(|w| !(*w >= 0.0)) {
            return None;
        }
        let cs = source.iter().zip(weights).map(|(p, w)| p * *w).sum::<Vec3>() / total;
        let ct = target.iter().zip(weights).map(|(p, w)| p * *w).sum::<Vec3>() / total;
        let mut h = Matrix3::zeros();
        for ((s, t), w) in source.iter().zip(target).zip(weights) {
            h += (s - cs) * (t - ct).transpose() * *w;
        }
        let svd = h.svd(true, true);
        let (u, v_t) = (svd.u?, svd.v_t?);
        // Collinear or coincident points leave the rotation about their line undetermined.
        // An array, not a Vec: the labeler calls this in its per-frame loop.
        let mut sv = [svd.singular_values[0], svd.singular_values[1], svd.singular_values[2]];
        sv.sort_by(|a, b| b.total_cmp(a));
        if sv[1].partial_cmp(&(1e-9 * sv[0].max(1e-300))) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        Some(Kabsch { source_centre: cs, target_centre: ct, u, v: v_t.transpose() })
    }

    /// The best proper rotation `V D U^T` (the reflection check in `D`) and its translation,
    /// for the source's `u` and centre (the set's own, or its mirror image's).
    fn proper(&self, u: Matrix3<f64>, source_centre: Vec3) -> Option<RigidTransform> {
        let mut d = Matrix3::identity();
        if (self.v * u.transpose()).determinant() < 0.0 {
            d[(2, 2)] = -1.0;
        }
        let r = self.v * d * u.transpose();
        let rotation = Rotation3::from_matrix_unchecked(r);
        let translation = self.target_centre - rotation * source_centre;
        if !(translation.iter().all(|x| x.is_finite()) && r.iter().all(|x| x.is_finite())) {
            return None;
        }
        Some(RigidTransform { rotation, translation })
    }
}

/// Root-mean-square distance between `transform(source[k])` and `target[k]`.
pub fn rms_error(transform: &RigidTransform, source: &[Vec3], target: &[Vec3]) -> f64 {
    let sum: f64 = source.iter().zip(target).map(|(s, t)| (transform.apply(s) - t).norm_squared()).sum();
    (sum / source.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Unit, Vector3};
    use proptest::prelude::*;

    fn points() -> Vec<Vec3> {
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(100.0, 0.0, 0.0),
            Vec3::new(0.0, 80.0, 0.0),
            Vec3::new(10.0, 20.0, 60.0),
            Vec3::new(-40.0, 30.0, 15.0),
        ]
    }

    #[test]
    fn one_svd_aligns_a_set_and_its_mirror_image_as_two_would() {
        let source = points();
        let mirrored: Vec<Vec3> = source.iter().map(|p| Vec3::new(p.x, p.y, -p.z)).collect();
        let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -1.0, 0.5)), 0.9);
        let target: Vec<Vec3> = source.iter().map(|p| turn * p + Vec3::new(5.0, -7.0, 300.0)).collect();
        let weights = [1.0, 0.5, 2.0, 1.5, 0.25];
        let both = align_weighted_and_mirrored(&source, &target, &weights).unwrap();
        for (got, points) in both.iter().zip([&source, &mirrored]) {
            let want = align_weighted(points, &target, &weights).unwrap();
            assert_relative_eq!(got.rotation.matrix(), want.rotation.matrix(), epsilon = 1e-9);
            assert_relative_eq!(got.translation, want.translation, epsilon = 1e-6);
        }
        // The set itself is mapped exactly; its mirror image is not.
        assert!(rms_error(&both[0], &source, &target) < 1e-9);
        assert!(rms_error(&both[1], &mirrored, &target) > 1.0);
    }

    #[test]
    fn the_inverse_undoes_the_transform() {
        let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -1.0, 0.5)), 0.9);
        let t = RigidTransform { rotation: turn, translation: Vec3::new(5.0, -7.0, 300.0) };
        for p in points() {
            assert_relative_eq!(t.apply_inverse(&t.apply(&p)), p, epsilon = 1e-9);
            assert_relative_eq!(t.apply(&t.apply_inverse(&p)), p, epsilon = 1e-9);
        }
    }

    #[test]
    fn a_mirror_image_is_aligned_by_a_proper_rotation() {
        let source = points();
        let mirrored: Vec<Vec3> = source.iter().map(|p| Vec3::new(p.x, p.y, -p.z)).collect();
        let t = align(&source, &mirrored).unwrap();
        assert_relative_eq!(t.rotation.matrix().determinant(), 1.0, epsilon = 1e-9);
        // The best proper fit of a mirror image cannot be exact.
        assert!(rms_error(&t, &source, &mirrored) > 1.0);
    }

    #[test]
    fn zero_weight_ignores_a_point() {
        let source = points();
        let shift = Vec3::new(5.0, -3.0, 2.0);
        let mut target: Vec<Vec3> = source.iter().map(|p| p + shift).collect();
        target[4] += Vec3::new(40.0, 0.0, 0.0);
        let t = align_weighted(&source, &target, &[1.0, 1.0, 1.0, 1.0, 0.0]).unwrap();
        assert!((t.apply(&source[0]) - target[0]).norm() < 1e-9);
        assert!(align_weighted(&source, &target, &[0.0; 5]).is_none());
        assert!(align_weighted(&source, &target, &[1.0, -1.0, 1.0, 1.0, 1.0]).is_none());
    }

    #[test]
    fn degenerate_inputs_are_refused() {
        let line: Vec<Vec3> = (0..4).map(|i| Vec3::new(i as f64, 0.0, 0.0)).collect();
        assert!(align(&line, &line).is_none());
        assert!(align(&points()[..2], &points()[..2]).is_none());
        assert!(align(&points(), &points()[..4]).is_none());
    }

    proptest! {
        #[test]
        fn recovers_any_rigid_motion(axis in proptest::array::uniform3(-1.0f64..1.0), angle in -3.1f64..3.1,
                                     shift in proptest::array::uniform3(-1e3f64..1e3)) {
            let axis = Vector3::from(axis);
            prop_assume!(axis.norm() > 0.1);
            let rotation = Rotation3::from_axis_angle(&Unit::new_normalize(axis), angle);
            let source = points();
            let target: Vec<Vec3> = source.iter().map(|p| rotation * p + Vec3::from(shift)).collect();
            let t = align(&source, &target).unwrap();
            prop_assert!(rms_error(&t, &source, &target) < 1e-6);
            prop_assert!((t.rotation.matrix().determinant() - 1.0).abs() < 1e-9);
        }
    }
}
