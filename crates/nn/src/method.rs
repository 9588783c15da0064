//! How a take becomes motion: the network solver ([`crate::solver`], LocalMoCap section 3.2),
//! the kinematic solver ([`crate::kinematic`], Table 1's optimization-based column), or the
//! network's answer refined by the kinematic solver ([`KinematicSolver::refine`]); and the
//! rule the default follows. One call, [`solve_take`], serves `locap solve` and the Python
//! `solve` alike.
//!
//! # The default ([`SolveMethod::Auto`])
//! - The network's markers are all in the take and the kinematic solver's layout fits it:
//!   the network refined by the kinematic solver. The network alone is a per-frame answer on
//!   bones it predicts, with no temporal consistency: on real takes its wrist joints leave
//!   their wrist markers (within 60 mm in only 74-79% of frames on CMU 01_01 and 02_01). The
//!   refinement keeps the network's rotations where the markers say little and puts the
//!   joints where the markers are, on bones calibrated to the subject. On the held-out
//!   subject it is better than the network on joint rotations and positions alike, at a
//!   thirtieth of the speed (docs/benchmarks.md, "The refinement as the default").
//! - Otherwise, where the kinematic solver's layout fits the take (another marker set with a
//!   layout): the kinematic solver alone.
//! - Otherwise the network, which says why it cannot solve the take.

use crate::NnError;
use crate::kinematic::{KinematicReport, KinematicSolver};
use crate::solver::Solver;
use locap_clean::{Cleaned, Filler};
use locap_core::{Motion, Take};

/// How to solve a take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveMethod {
    /// The refinement where the network's markers are all in the take, else the kinematic
    /// solver where its layout fits, else the network (see the module docs).
    Auto,
    /// The network solver alone.
    Network,
    /// The kinematic solver alone.
    Kinematic,
    /// The network's answer refined by the kinematic solver.
    Refine,
}

impl SolveMethod {
    /// What this method is on `take`: [`SolveMethod::Auto`] resolved by the rule of the module
    /// docs, any other method itself. Without a kinematic solver only the network can solve.
    pub fn resolve(self, take: &Take, network: &Solver, kinematic: Option<&KinematicSolver>) -> SolveMethod {
        let Some(kinematic) = kinematic else { return SolveMethod::Network };
        match self {
            SolveMethod::Auto => {
                let network_fits = crate::features::marker_order(take, &network.meta.markers).is_ok();
                match (network_fits, kinematic.fits(take)) {
                    (true, true) if kinematic.refines(network) => SolveMethod::Refine,
                    (false, true) => SolveMethod::Kinematic,
                    _ => SolveMethod::Network,
                }
            }
            other => other,
        }
    }

    /// How the summary names it.
    pub fn describe(self) -> &'static str {
        match self {
            SolveMethod::Auto => "auto",
            SolveMethod::Network => "network",
            SolveMethod::Kinematic => "kinematic",
            SolveMethod::Refine => "network refined by the kinematic solver",
        }
    }
}

/// A take solved by [`solve_take`].
#[derive(Debug, Clone)]
pub struct TakeSolve {
    /// The motion, in the skeleton's Y-up frame (as both solvers return it).
    pub motion: Motion,
    /// The take as cleaned before solving.
    pub cleaned: Cleaned,
    /// The method that solved it ([`SolveMethod::Auto`] resolved).
    pub method: SolveMethod,
    /// The kinematic solver's report, where it ran.
    pub report: Option<KinematicReport>,
}

/// Cleans `take` (gaps filled by `filler`) and solves it with `method` ([`SolveMethod::resolve`]).
/// `kinematic` is needed by every method but [`SolveMethod::Network`].
///
/// # Errors
/// The chosen solver cannot solve the take (another marker set, no frames), the filler cannot
/// run on it, or a kinematic method without a kinematic solver.
pub fn solve_take(
    take: &Take,
    filler: &dyn Filler,
    network: &Solver,
    kinematic: Option<&KinematicSolver>,
    method: SolveMethod,
) -> Result<TakeSolve, NnError> {
    let method = match (method, kinematic) {
        (SolveMethod::Kinematic | SolveMethod::Refine, None) => {
            return Err(NnError::Kinematic(format!("--method {method:?} needs a kinematic solver")));
        }
        _ => method.resolve(take, network, kinematic),
    };
    match (method, kinematic) {
        (SolveMethod::Refine, Some(k)) => {
            let (prior, cleaned) = network.solve(take, filler)?;
            let (motion, report) = k.refine(&cleaned, take.frame_rate_hz(), &prior)?;
            Ok(TakeSolve { motion, cleaned, method, report: Some(report) })
        }
        (SolveMethod::Kinematic, Some(k)) => {
            let (motion, cleaned, report) = k.solve(take, filler)?;
            Ok(TakeSolve { motion, cleaned, method, report: Some(report) })
        }
        _ => {
            let (motion, cleaned) = network.solve(take, filler)?;
            Ok(TakeSolve { motion, cleaned, method: SolveMethod::Network, report: None })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Vec3};
    use locap_synth::Layout;

    fn take(labels: &[&str]) -> Take {
        let names = labels.iter().map(|l| MarkerName::parse(l)).collect::<Vec<_>>();
        let samples: Vec<Option<Vec3>> = (0..2 * labels.len()).map(|i| Some(Vec3::new(i as f64, 1.0, 0.0))).collect();
        Take::from_samples(names, &samples, 120.0).unwrap()
    }

    /// The default refines a take of the network's marker set, solves a take of the layout's
    /// alone where the network's markers are not all there, and needs the network elsewhere;
    /// a method asked for by name is kept.
    #[test]
    fn the_default_refines_where_the_network_fits_and_solves_kinematically_elsewhere() {
        let network = crate::shipped::solver(&Default::default()).unwrap();
        let kinematic = KinematicSolver::cmu41().unwrap();
        assert!(kinematic.refines(&network));
        let all: Vec<&str> = network.meta.markers.iter().map(String::as_str).collect();
        let full = take(&all);
        let auto = SolveMethod::Auto;
        assert_eq!(auto.resolve(&full, &network, Some(&kinematic)), SolveMethod::Refine);
        assert_eq!(auto.resolve(&full, &network, None), SolveMethod::Network);
        assert_eq!(SolveMethod::Network.resolve(&full, &network, Some(&kinematic)), SolveMethod::Network);
        assert_eq!(SolveMethod::Kinematic.resolve(&full, &network, Some(&kinematic)), SolveMethod::Kinematic);
        // One marker short of the network's set: the layout still fits.
        let short = take(&all[1..]);
        assert_eq!(auto.resolve(&short, &network, Some(&kinematic)), SolveMethod::Kinematic);
        // Neither fits: the network, which names what is missing.
        let other = take(&["A", "B", "C", "D"]);
        assert_eq!(auto.resolve(&other, &network, Some(&kinematic)), SolveMethod::Network);
        let error = solve_take(&other, &locap_clean::FillConfig::default(), &network, Some(&kinematic), auto);
        assert!(error.is_err());
        // A kinematic method needs its solver.
        let error = solve_take(&full, &locap_clean::FillConfig::default(), &network, None, SolveMethod::Refine);
        assert!(matches!(error, Err(NnError::Kinematic(_))), "{error:?}");
    }

    /// A layout skeleton whose joints the network does not have is not refined by it: the
    /// missing joints would be held at rest.
    #[test]
    fn another_skeleton_is_not_refined_by_the_network() {
        let network = crate::shipped::solver(&Default::default()).unwrap();
        let hand = Layout::from_toml(include_str!("../../synth/layouts/hand-left.toml")).unwrap();
        let kinematic = KinematicSolver::from_layout(&hand).unwrap();
        assert!(!kinematic.refines(&network));
        let names: Vec<&str> = kinematic.markers().iter().map(String::as_str).collect();
        let hand_take = take(&names);
        assert_eq!(SolveMethod::Auto.resolve(&hand_take, &network, Some(&kinematic)), SolveMethod::Kinematic);
    }
}
