//! Rigid alignment of corresponding point sets (orthogonal Procrustes, Kabsch's SVD solution).
//!
//! Used twice in cleaning: EDM aligns its MDS embedding onto the visible neighbours (paper
//! section 3.1, "Rotation Orthogonal Procrustes Problem", closed form by SVD), and the rigid
//! baseline carries a marker along with three neighbours. The reflection handling is ours
//! because no crate offers what both uses need, and so is the 3x3 SVD (`svd3`, nalgebra's
//! method with a Jacobi eigen-solver in place of its general one, which took a fifth of
//! `locap clean`'s time in these alignments; docs/benchmarks.md).

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
        let (u, sv, v) = svd3(&h)?;
        // Collinear or coincident points leave the rotation about their line undetermined.
        if sv[1].partial_cmp(&(1e-9 * sv[0].max(1e-300))) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        Some(Kabsch { source_centre: cs, target_centre: ct, u, v })
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

/// Sweeps of [`symmetric_eigenvectors3`] at most; a 3x3 matrix converges in 4-6.
const JACOBI_SWEEPS: usize = 32;

/// The SVD `h = U diag(sv) V^T` of a 3x3 matrix, singular values in decreasing order: the
/// eigenvectors `V` of `h^T h`, then `U` and the singular values from the Gram-Schmidt QR of
/// `h V` (McAdams et al. 2011, as nalgebra's `svd_ordered3`, whose general-purpose
/// eigen-solver took a fifth of `locap clean`'s time in these alignments). `None` where `h`
/// is not finite or is zero.
fn svd3(h: &Matrix3<f64>) -> Option<(Matrix3<f64>, [f64; 3], Matrix3<f64>)> {
    if !h.iter().all(|x| x.is_finite()) {
        return None;
    }
    let mut v = symmetric_eigenvectors3(h.transpose() * h);
    let mut b = h * v;
    // Columns by decreasing norm (the QR's diagonal then decreases), V kept a rotation.
    let mut order = [0, 1, 2];
    order.sort_by(|&x, &y| b.column(y).norm_squared().total_cmp(&b.column(x).norm_squared()));
    let (v0, b0) = (v, b);
    for (to, &from) in order.iter().enumerate() {
        v.set_column(to, &v0.column(from));
        b.set_column(to, &b0.column(from));
    }
    if v.determinant() < 0.0 {
        v.set_column(2, &-v.column(2));
        b.set_column(2, &-b.column(2));
    }
    let b: [Vec3; 3] = [b.column(0).into_owned(), b.column(1).into_owned(), b.column(2).into_owned()];
    let r0 = b[0].norm();
    if !(r0 > 0.0) {
        return None;
    }
    let u0 = b[0] / r0;
    let w1 = b[1] - u0 * u0.dot(&b[1]);
    // Twice: where `b[1]` is almost along `u0`, one pass leaves a remainder that is not.
    let w1 = w1 - u0 * u0.dot(&w1);
    let r1 = w1.norm();
    // A rank-one `h`: any unit vector normal to `u0` completes the basis.
    let u1 = if r1 > 0.0 { w1 / r1 } else { any_normal(&u0) };
    let normal = u0.cross(&u1);
    let r2 = normal.dot(&b[2]);
    let u2 = if r2 < 0.0 { -normal } else { normal };
    Some((Matrix3::from_columns(&[u0, u1, u2]), [r0, r1, r2.abs()], v))
}

/// A unit vector normal to the unit vector `u`.
fn any_normal(u: &Vec3) -> Vec3 {
    let axis = if u.x.abs() < 0.6 { Vec3::x() } else { Vec3::y() };
    (axis - u * u.dot(&axis)).normalize()
}

/// The eigenvectors of a symmetric 3x3 matrix by cyclic Jacobi rotations, as the columns of a
/// rotation, in no particular order.
fn symmetric_eigenvectors3(m: Matrix3<f64>) -> Matrix3<f64> {
    // Plain arrays: with constant indices the compiler keeps every entry in registers.
    let mut a =
        [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]];
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..JACOBI_SWEEPS {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diagonal = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if !(off > f64::EPSILON * f64::EPSILON * diagonal) {
            break;
        }
        rotate::<0, 1, 2>(&mut a, &mut v);
        rotate::<0, 2, 1>(&mut a, &mut v);
        rotate::<1, 2, 0>(&mut a, &mut v);
    }
    Matrix3::new(v[0][0], v[0][1], v[0][2], v[1][0], v[1][1], v[1][2], v[2][0], v[2][1], v[2][2])
}

/// One Jacobi rotation of [`symmetric_eigenvectors3`]: the rotation in the `(P, Q)` plane that zeroes
/// `a[P][Q]` (Numerical Recipes 11.1), applied to `a` (`R` the third index) and accumulated in
/// `v`'s columns.
fn rotate<const P: usize, const Q: usize, const R: usize>(a: &mut [[f64; 3]; 3], v: &mut [[f64; 3]; 3]) {
    let apq = a[P][Q];
    if apq == 0.0 {
        return;
    }
    let theta = (a[Q][Q] - a[P][P]) / (2.0 * apq);
    let t =
        if theta.abs() > 1e150 { 0.5 / theta } else { theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt()) };
    let c = 1.0 / (t * t + 1.0).sqrt();
    let s = t * c;
    let tau = s / (1.0 + c);
    a[P][P] -= t * apq;
    a[Q][Q] += t * apq;
    a[P][Q] = 0.0;
    a[Q][P] = 0.0;
    let (arp, arq) = (a[R][P], a[R][Q]);
    a[R][P] = arp - s * (arq + tau * arp);
    a[R][Q] = arq + s * (arp - tau * arq);
    a[P][R] = a[R][P];
    a[Q][R] = a[R][Q];
    for row in v.iter_mut() {
        let (vp, vq) = (row[P], row[Q]);
        row[P] = vp - s * (vq + tau * vp);
        row[Q] = vq + s * (vp - tau * vq);
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

        /// The 3x3 SVD agrees with nalgebra's general one: the same singular values, the
        /// product restores the matrix, and both factors are orthonormal; also for the rank-two
        /// cross-covariance of three points (the rigid fill's) and rank one.
        #[test]
        fn the_3x3_svd_agrees_with_nalgebras(entries in proptest::array::uniform9(-1e3f64..1e3), rank in 1usize..4) {
            let m = Matrix3::from_row_slice(&entries);
            let m = match rank {
                1 => m.column(0) * m.row(1),
                2 => m - m.column(0) * m.column(0).transpose() * m / m.column(0).norm_squared().max(1e-300),
                _ => m,
            };
            prop_assume!(m.norm() > 1e-6);
            let (u, sv, v) = svd3(&m).unwrap();
            let restored = u * Matrix3::from_diagonal(&Vec3::from(sv)) * v.transpose();
            prop_assert!((restored - m).norm() < 1e-9 * m.norm());
            prop_assert!((u.transpose() * u - Matrix3::identity()).norm() < 1e-9);
            prop_assert!((v.transpose() * v - Matrix3::identity()).norm() < 1e-9);
            let mut reference: Vec<f64> = m.svd(false, false).singular_values.iter().copied().collect();
            reference.sort_by(|a, b| b.total_cmp(a));
            for (ours, theirs) in sv.iter().zip(&reference) {
                prop_assert!((ours - theirs).abs() < 1e-9 * m.norm(), "{sv:?} against {reference:?}");
            }
        }

        /// Three points, the rigid fill's case (a rank-two cross-covariance), in any motion.
        #[test]
        fn aligns_three_points(axis in proptest::array::uniform3(-1.0f64..1.0), angle in -3.1f64..3.1,
                               noise in proptest::array::uniform9(-2.0f64..2.0)) {
            let axis = Vector3::from(axis);
            prop_assume!(axis.norm() > 0.1);
            let rotation = Rotation3::from_axis_angle(&Unit::new_normalize(axis), angle);
            let source = points()[..3].to_vec();
            let target: Vec<Vec3> = source
                .iter()
                .enumerate()
                .map(|(k, p)| rotation * p + Vec3::new(noise[3 * k], noise[3 * k + 1], noise[3 * k + 2]))
                .collect();
            let t = align(&source, &target).unwrap();
            // The best proper rotation is no worse than the true one.
            let truth = RigidTransform { rotation, translation: Vec3::zeros() };
            let centred = |set: &[Vec3]| set.iter().sum::<Vec3>() / set.len() as f64;
            let truth = RigidTransform { translation: centred(&target) - rotation * centred(&source), ..truth };
            prop_assert!(rms_error(&t, &source, &target) <= rms_error(&truth, &source, &target) + 1e-9);
            prop_assert!((t.rotation.matrix().determinant() - 1.0).abs() < 1e-9);
        }
    }
}
