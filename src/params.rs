//! Parameters of every stage, with the paper's defaults. Lengths are fractions
//! of the longest side of the sequence's bounding box unless
//! `absolute_units` is set (method.md §9): the paper's ρ = 0.125 m on a
//! 1.8 m human becomes 0.07, so one default serves millimetres and metres.

use crate::math::Real;

/// Which affinity weights the rigid fits (method.md §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AffinityKind {
    /// The paper's maximum-distance affinity (default).
    Max,
    /// The earlier IIR-filtered affinity of [8], kept for comparison.
    Iir,
}

/// Forward tracking (method.md §2-§5).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct TrackParams {
    /// Number of centers N. Default 1000; 1 ..= occupied voxels of frame 0.
    pub centers: usize,
    /// Seed of the initial center placement. Default 0.
    pub seed: u64,
    /// Affinity kind. Default [`AffinityKind::Max`].
    pub affinity: AffinityKind,
    /// ρ_p: distance at which the positional affinity is 0.5. Default 0.07
    /// (relative; the paper's 0.125 m on a ~1.8 m human); > 0.
    pub rho_p: Real,
    /// ρ_m: motion dissimilarity at which the motion affinity is 0.5.
    /// Default 0.07 (relative; the paper's 0.125 m); > 0.
    pub rho_m: Real,
    /// α: IIR filter weight of the newest motion affinity (`iir` only).
    /// Default 0.05; in (0, 1].
    pub alpha: Real,
    /// β: weight of the centroid (data) term against the rigid prediction.
    /// Default 1; > 0.
    pub beta: Real,
    /// μ: affinities below this are dropped from the neighbour lists.
    /// Default 0.001; in (0, 1).
    pub mu: Real,
    /// Steps of pure rigid prediction before the data term enters. Default 10.
    pub presmooth_steps: usize,
    /// Convergence: stop when no center moves farther than this in one
    /// iteration. Default 5.6e-5 (relative; the reference's 1e-4 m); > 0.
    pub threshold: Real,
    /// Iteration limit per frame. Default 1000; >= 1.
    pub max_iterations: usize,
    /// Lloyd iterations placing the centers in frame 0. Default 100.
    pub lloyd_iterations: usize,
    /// Over-relaxation of those Lloyd iterations (c += ω (x̄ - c)).
    /// Default 1.8; in (0, 2).
    pub over_relaxation: Real,
    /// Take ρ_p, ρ_m and threshold in the input's units instead of as
    /// fractions of the bounding box's longest side. Default false.
    pub absolute_units: bool,
}

impl Default for TrackParams {
    fn default() -> Self {
        TrackParams {
            centers: 1000,
            seed: 0,
            affinity: AffinityKind::Max,
            rho_p: 0.07,
            rho_m: 0.07,
            alpha: 0.05,
            beta: 1.0,
            mu: 0.001,
            presmooth_steps: 10,
            threshold: 5.6e-5,
            max_iterations: 1000,
            lloyd_iterations: 100,
            over_relaxation: 1.8,
            absolute_units: false,
        }
    }
}

impl TrackParams {
    /// Checks every field's range.
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |what: &str| Err(crate::Error::InvalidParameter(what.to_string()));
        if self.centers == 0 {
            return bad("--centers must be at least 1");
        }
        if !(self.rho_p > 0.0 && self.rho_m > 0.0 && self.rho_p.is_finite() && self.rho_m.is_finite()) {
            return bad("rho_p and rho_m must be positive");
        }
        if !(self.alpha > 0.0 && self.alpha <= 1.0) {
            return bad("alpha must be in (0, 1]");
        }
        if !(self.beta > 0.0 && self.beta.is_finite()) {
            return bad("beta must be positive");
        }
        if !(self.mu > 0.0 && self.mu < 1.0) {
            return bad("mu must be in (0, 1)");
        }
        if !(self.threshold > 0.0 && self.threshold.is_finite()) {
            return bad("threshold must be positive");
        }
        if self.max_iterations == 0 {
            return bad("max_iterations must be at least 1");
        }
        if !(self.over_relaxation > 0.0 && self.over_relaxation < 2.0) {
            return bad("over_relaxation must be in (0, 2)");
        }
        Ok(())
    }

    /// Factor from this struct's lengths to the input's units.
    pub fn length_scale(&self, bounds: &crate::mesh::Aabb) -> Real {
        if self.absolute_units {
            1.0
        } else {
            bounds.longest_side()
        }
    }
}

/// σ such that exp(-σ ρ²) = 0.5.
pub fn sigma_for(rho: Real) -> Real {
    std::f64::consts::LN_2 / (rho * rho)
}
