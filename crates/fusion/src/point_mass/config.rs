//! The config of `pmf` and its checks.

use serde::{Deserialize, Serialize};
use wipdr_core::ConfigError;

use crate::FusionError;

/// `pmf`'s default [`crate::fix_error::RadiusConfig::bias_share`]: smaller than the other
/// schemes' (its lattice already holds a second mode's weight and `sd_floor_m`).
pub const PMF_BIAS_SHARE: f64 = 0.2;

/// Config of `pmf`. The defaults were chosen on the five ILC floors (`docs/sweeps/pmf-grid.toml`,
/// `docs/sweeps/pmf-outlier-gap-wifi-sd.toml`; docs/experiments.md), so they are optimistic there;
/// [`PointMassConfig::paper`] keeps the settings before the second of those sweeps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PointMassConfig {
    /// Lattice spacing of the offset hypotheses, metres.
    pub cell_m: f64,
    /// Margin around the floor plan (or, without a plan, half-width of the lattice around
    /// the first fix), metres.
    pub margin_m: f64,
    /// Variance added to the offset per step (PDR drift), m².
    pub drift_m2_per_step: f64,
    /// Weight of a hypothesis whose position is inside a unit (a shop), per step (0.65;
    /// [`PointMassConfig::paper`]: 0.8). 0.65 measured ILC causal 5.03 -> 4.98 m against 0.8,
    /// offline 4.02 -> 3.84 m, better offline on every floor
    /// (`just sweep docs/sweeps/pmf-unit-likelihood.toml s.csv`, docs/experiments.md);
    /// harder (0.5) lowers the median further but places some walks in the wrong corridor.
    pub unit_likelihood: f64,
    /// Weight of a hypothesis whose position is outside the floor outline, per step.
    pub outside_likelihood: f64,
    /// Standard deviation of a good Wi-Fi fix, metres (5; [`PointMassConfig::paper`]: 6).
    pub wifi_sd_m: f64,
    /// Outlier floor of the Wi-Fi likelihood (relative to its peak of 1; 0.05,
    /// [`PointMassConfig::paper`]: 0.1).
    pub wifi_outlier: f64,
    /// Distance from the nearest reference point beyond which a position counts as a
    /// coverage gap, metres (15; 0: no coverage awareness; also off when the filter is built
    /// without the radio map's reference points).
    pub gap_distance_m: f64,
    /// Peak Wi-Fi likelihood of a hypothesis in a coverage gap (relative to a peak of 1 in
    /// covered space): a fix there lands at some covered place near the walker, so the
    /// likelihood is a wide Gaussian of standard deviation `gap_sd_m` (plus the outlier floor).
    pub gap_likelihood: f64,
    /// Standard deviation of the fix about a walker in a coverage gap, metres (35;
    /// [`PointMassConfig::paper`]: 20).
    pub gap_sd_m: f64,
    /// Recovery floor after each update, as a share of the uniform probability.
    pub recovery: f64,
    /// Radius around the most probable cell over which the estimate is taken (mean or median,
    /// `estimate_median`), metres
    /// (0: the whole posterior).
    pub estimate_radius_m: f64,
    /// Report the posterior's geometric median within `estimate_radius_m` of the mode (the
    /// point of least expected error, the metric the evaluation scores) instead of its mean
    /// (true; [`PointMassConfig::paper`]: false, the mean). The median measured ILC causal
    /// 5.05 -> 5.03 m, better or equal on every floor; IPIN causal mean 7.05 unchanged, its
    /// EvAAL 9.78 -> 9.82 m slightly worse (`just sweep docs/sweeps/pmf-estimate-median.toml
    /// s.csv`, docs/experiments.md).
    pub estimate_median: bool,
    /// Standard deviation added (in quadrature, per axis) to the posterior's spread in the
    /// reported covariance, metres: the walker's offset from the placed PDR track (its local
    /// shape error), which the lattice over placements does not hold. 2.5 m puts the truth
    /// inside the 95 % radius at 92 % of the five ILC floors' waypoints (81.6 % without;
    /// `docs/results/accuracy.md`). Moves no estimate. wipdr's own (no paper value).
    pub sd_floor_m: f64,
    /// The reported covariance also keeps `radius.bias_share` of the Wi-Fi variance learned
    /// from the fixes' residuals ([`crate::fix_error`]): where the fixes are worse than on the
    /// ILC floors (the IPIN building), the radius grows with them. Moves no estimate.
    pub radius: crate::fix_error::RadiusConfig,
    /// Standard deviation added (in quadrature, per axis) to the reported covariance for each
    /// metre the estimate lies from the radio map's coverage (its nearest reference point;
    /// the distance counts up to `gap_distance_m` plus two cells), metres per metre: in a
    /// coverage gap the fixes share a bias the lattice cannot see, so the radius grows there.
    /// Needs the coverage raster (`gap_distance_m` > 0 and the map's reference points).
    /// Moves no estimate. 1.0 ([`PointMassConfig::paper`]: 0, off) measured against 0: the
    /// share of scored waypoints inside the 95 % radius went 94.3 -> 95.9 % on the five ILC
    /// floors (66.7 -> 83.3 % of those 12 m or more from coverage) and 79.8 -> 86.0 % on
    /// IPIN, the median radius 9.3 -> 9.8 m and 10.9 -> 11.6 m
    /// (`just sweep docs/sweeps/pmf-gap-radius.toml s.csv`, docs/experiments.md).
    /// wipdr's own (no paper value).
    pub gap_radius_sd_per_m: f64,
    /// Signal distance of a fix's best candidate at which its Gaussian part is halved (the
    /// matcher's distance unit; 0: every fix trusted alike).
    pub quality_distance: f64,
    /// Softness of that logistic, in the same unit.
    pub quality_softness: f64,
    /// Distance walked over which two fixes' errors decorrelate, metres (0: every fix is
    /// independent). A fix after `d` metres of walking weighs its Gaussian part with the
    /// power `max(min_fix_weight, min(1, d / fix_decorrelation_m))`: fixes taken standing
    /// still repeat one biased answer and count as a fraction of one. Off by default: it
    /// helps the IPIN logfiles' standing minute and costs the ILC floors
    /// (`docs/experiments.md`, fix decorrelation). wipdr's own.
    pub fix_decorrelation_m: f64,
    /// Least power of a fix's Gaussian part (see `fix_decorrelation_m`), in (0, 1].
    pub min_fix_weight: f64,
    /// Half-width of the square over which a mode's probability is summed, metres.
    pub mode_radius_m: f64,
    /// Keep the previous mode while it holds at least this share of the best mode's mass
    /// (1: only while it ties with the best, no stickiness; [`PointMassConfig::paper`]: 0.5).
    /// 1 measured ILC causal 5.10 -> 5.05 m against 0.5, better or equal on every floor
    /// (`just sweep docs/sweeps/pmf-mode-hysteresis.toml s.csv`, docs/experiments.md).
    pub mode_hysteresis: f64,
    /// Multiplies every step length (1 = as PDR reports).
    pub step_scale: f64,
    /// Added to every step's heading, degrees (0 = as PDR reports): one hypothesis of a
    /// constant PDR heading bias.
    pub heading_offset_deg: f64,
    /// Constant PDR heading biases, degrees, each run as its own lattice and weighed by its
    /// evidence ([`super::PointMassMixture`]); each is added to `heading_offset_deg`. Empty:
    /// one lattice. Every entry multiplies the work.
    pub heading_hypotheses_deg: Vec<f64>,
    /// Constant step-length scales (a walker's stride against the calibrated model), each
    /// multiplying `step_scale`, run as lattices of their own like the heading hypotheses
    /// (with both, every pair is one lattice: at most
    /// [`super::MAX_HEADING_HYPOTHESES`] in all). Empty: one scale.
    pub step_scale_hypotheses: Vec<f64>,
    /// Width (a Gaussian's standard deviation, metres) of the training trails
    /// ([`crate::trails`]) in the per-step weight on every plan; 0 (the default and
    /// `paper()`): off where the plan has walls (a walkable raster), `planless_trail_sd_m`
    /// where it has none. Off when the filter is built without trails. With walls the trails
    /// cost accuracy on the ILC floors (`just sweep docs/sweeps/pmf-trails.toml s.csv`,
    /// docs/experiments.md; docs/results/trails.md).
    pub trail_sd_m: f64,
    /// Width of the training trails used when `trail_sd_m` is 0 and the filter has no
    /// walkable raster (a plan without an outline: the IPIN logfiles, ILC sites read as one
    /// building), where the trails are the only knowledge of where people walk. Default 6 m
    /// (sweep `docs/sweeps/pmf-planless-trails.toml`: IPIN causal 7.05 -> 6.78 m,
    /// EvAAL 9.82 -> 9.43; offline 6.08 -> 5.82, EvAAL 6.70 -> 6.38; ILC sites as buildings
    /// 6.07 -> 5.51); `paper()`: 0 (off).
    pub planless_trail_sd_m: f64,
    /// Per-step weight of a hypothesis far from every training trail (relative to 1 on a
    /// trail): the weight is `off + (1 - off) exp(-d² / 2 sd²)`. Default 0.8 (a gentle pull:
    /// with 0.5 IPIN causal is 6.69 / EvAAL 9.28 but offline EvAAL 7.03 against 6.38);
    /// `paper()`: 0.5.
    pub off_trail_likelihood: f64,
    /// Weigh the cells by the scan's likelihood over the floor
    /// ([`wipdr_core::WifiLikelihood`], when the fix carries one) instead of the robust
    /// Gaussian about the fix: a scan that fits two places keeps both until the walk's shape
    /// and the plan choose. The coverage-gap terms (`gap_*`, `quality_*`) do not apply: a
    /// place the radio map does not know reads its known neighbours' likelihood. A fix
    /// without a likelihood is weighed by the Gaussian. On by default, mixed half and half
    /// with the Gaussian (`likelihood_share`): five ILC floors causal 4.98 -> 4.77 m (p95
    /// 13.61 -> 13.09), IPIN EvAAL 9.33 -> 9.19 (`docs/results/likelihood.md`);
    /// [`PointMassConfig::paper`]: off.
    pub wifi_likelihood: bool,
    /// With `wifi_likelihood`, the likelihood's share of a cell's Wi-Fi weight, in `[0, 1]`:
    /// the weight is `(1 - share) g + share l + wifi_outlier` with `g` the Gaussian about
    /// the fix (coverage aware) and `l` the scan's likelihood relative to its best cell.
    /// 1: the likelihood alone. 0.5: the five ILC floors' causal mean 4.80 / 4.73 / 4.96 m
    /// at 0.4 / 0.5 / 0.6 (the likelihood alone 6.13 m: a place the point would have ruled
    /// out keeps weight), `docs/results/likelihood.md`.
    pub likelihood_share: f64,
}

impl Default for PointMassConfig {
    fn default() -> Self {
        Self {
            cell_m: 1.0,
            margin_m: 10.0,
            drift_m2_per_step: 0.05,
            unit_likelihood: 0.65,
            outside_likelihood: 0.3,
            wifi_sd_m: 5.0,
            wifi_outlier: 0.05,
            gap_distance_m: 15.0,
            gap_likelihood: 0.3,
            gap_sd_m: 35.0,
            recovery: 1e-6,
            estimate_radius_m: 10.0,
            estimate_median: true,
            sd_floor_m: 2.5,
            radius: crate::fix_error::RadiusConfig {
                bias_share: PMF_BIAS_SHARE,
                ..Default::default()
            },
            gap_radius_sd_per_m: 1.0,
            quality_distance: 0.0,
            quality_softness: 5.0,
            fix_decorrelation_m: 0.0,
            min_fix_weight: 0.2,
            mode_radius_m: 5.0,
            mode_hysteresis: 1.0,
            step_scale: 1.0,
            heading_offset_deg: 0.0,
            heading_hypotheses_deg: Vec::new(),
            step_scale_hypotheses: Vec::new(),
            trail_sd_m: 0.0,
            planless_trail_sd_m: 6.0,
            off_trail_likelihood: 0.8,
            wifi_likelihood: true,
            likelihood_share: 0.5,
        }
    }
}

impl PointMassConfig {
    /// `pmf` is wipdr's own scheme, in no paper: its preset is the settings it had before the
    /// five-floor sweeps that set its defaults (`wifi_outlier` 0.1, `gap_sd_m` 20 m, `wifi_sd_m`
    /// 6 m, `mode_hysteresis` 0.5, `estimate_median` false: the mean, no planless trails,
    /// `unit_likelihood` 0.8, no gap term in the radius, the Gaussian about the fix alone), the settings the "before" figures
    /// of `docs/experiments.md` were measured with.
    pub fn paper() -> Self {
        Self {
            wifi_sd_m: 6.0,
            wifi_outlier: 0.1,
            gap_sd_m: 20.0,
            mode_hysteresis: 0.5,
            estimate_median: false,
            planless_trail_sd_m: 0.0,
            off_trail_likelihood: 0.5,
            unit_likelihood: 0.8,
            gap_radius_sd_per_m: 0.0,
            wifi_likelihood: false,
            ..Self::default()
        }
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), FusionError> {
        let positive = [
            ("cell_m", self.cell_m),
            ("wifi_sd_m", self.wifi_sd_m),
            ("gap_sd_m", self.gap_sd_m),
            ("quality_softness", self.quality_softness),
            ("step_scale", self.step_scale),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be finite and > 0, got {v}"),
                )));
            }
        }
        let non_negative = [
            ("margin_m", self.margin_m),
            ("drift_m2_per_step", self.drift_m2_per_step),
            ("wifi_outlier", self.wifi_outlier),
            ("gap_distance_m", self.gap_distance_m),
            ("recovery", self.recovery),
            ("estimate_radius_m", self.estimate_radius_m),
            ("sd_floor_m", self.sd_floor_m),
            ("gap_radius_sd_per_m", self.gap_radius_sd_per_m),
            ("mode_radius_m", self.mode_radius_m),
            ("quality_distance", self.quality_distance),
            ("fix_decorrelation_m", self.fix_decorrelation_m),
            ("trail_sd_m", self.trail_sd_m),
            ("planless_trail_sd_m", self.planless_trail_sd_m),
        ];
        let lattices =
            self.heading_hypotheses_deg.len().max(1) * self.step_scale_hypotheses.len().max(1);
        if lattices > super::mixture::MAX_HEADING_HYPOTHESES {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                if self.step_scale_hypotheses.is_empty() {
                    "heading_hypotheses_deg"
                } else {
                    "step_scale_hypotheses"
                },
                format!(
                    "at most {} hypotheses (heading x step scale), got {} x {}",
                    super::mixture::MAX_HEADING_HYPOTHESES,
                    self.heading_hypotheses_deg.len().max(1),
                    self.step_scale_hypotheses.len().max(1)
                ),
            )));
        }
        if let Some(k) = self
            .step_scale_hypotheses
            .iter()
            .find(|k| !(k.is_finite() && (0.5..=2.0).contains(*k)))
        {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "step_scale_hypotheses",
                format!("every entry must be within [0.5, 2], got {k}"),
            )));
        }
        if let Some(h) = self
            .heading_hypotheses_deg
            .iter()
            .find(|h| !(h.is_finite() && h.abs() <= 180.0))
        {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "heading_hypotheses_deg",
                format!("every entry must be within [-180, 180], got {h}"),
            )));
        }
        if !(self.heading_offset_deg.is_finite() && self.heading_offset_deg.abs() <= 180.0) {
            return Err(FusionError::InvalidConfig(ConfigError::new(
                "heading_offset_deg",
                format!(
                    "must be within [-180, 180], got {}",
                    self.heading_offset_deg
                ),
            )));
        }
        for (field, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be finite and >= 0, got {v}"),
                )));
            }
        }
        let probabilities = [
            ("unit_likelihood", self.unit_likelihood),
            ("outside_likelihood", self.outside_likelihood),
            ("gap_likelihood", self.gap_likelihood),
            ("mode_hysteresis", self.mode_hysteresis),
            ("off_trail_likelihood", self.off_trail_likelihood),
            ("min_fix_weight", self.min_fix_weight),
        ];
        for (field, v) in probabilities {
            if !(v.is_finite() && v > 0.0 && v <= 1.0) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be in (0, 1], got {v}"),
                )));
            }
        }
        for (field, v) in [("likelihood_share", self.likelihood_share)] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(FusionError::InvalidConfig(ConfigError::new(
                    field,
                    format!("must be in [0, 1], got {v}"),
                )));
            }
        }
        self.radius.validate()
    }
}
