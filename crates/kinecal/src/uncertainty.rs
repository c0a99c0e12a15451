//! Uncertainty of a calibration, and the verdict on each change.
//!
//! The covariance of the estimated parameters is `s0^2 (J^T W J)^+` restricted to the determined
//! directions (the first `rank` singular vectors of the scaled Jacobian), with the variance
//! factor `s0^2 = SSR / (m - r)`: the weighted sum of squared residuals over the residual count
//! minus the rank (not the parameter count, which would overstate the degrees of freedom of a
//! redundant model). `s0` near 1 means the `--weights` match the actual noise. Only determined
//! quantities get a standard deviation: a parameter the data cannot separate from others has
//! none, and its group's combination is reported instead.
//!
//! The Jacobian is taken at a *reference* model, not at the calibrated point: the workflow's
//! one linearisation rule (see [`crate::workflow`]) passes the nominal robot for
//! minimum-change answers and the solver's starting robot otherwise. There a design's exact
//! redundancies (parallel axes) hold; at the calibrated point, noise breaks such exact
//! parallelism by a little, which would turn each exact redundancy into a barely determined
//! direction with an enormous standard deviation. To first order in the (small) parameter
//! changes the covariance is the same.
//!
//! **With a prior** (see [`crate::solve::problem`]) its `k` rows are rows like the data's `m`: the
//! rank `r` and the determined directions are those of the two together, the covariance is the
//! posterior one, `s0^2 (J^T W J + P)^+` with `P = diag(1 / s_p^2)` (scaled and truncated as
//! above), and [`Uncertainty::dof`] counts `m + k - r`. The variance factor, though, is the
//! data's: `s0^2 = SSR / (m - tr H_data)`, the data's squared residuals over the data's rows less
//! their leverage, `tr H_data = tr((J^T W J + P)^+ J^T W J) = r - sum_p C_pp / s_p^2` (`C` the
//! unscaled inverse information; the prior rows' leverage is `C_pp / s_p^2`). Why not `(SSR +
//! SSP) / (m + k - r)`, the prior's rows counted as observations: both are unbiased when the
//! prior's sigmas are the real spread of the changes, but the prior's residuals measure how far
//! the data pulled each parameter, not the measurement noise. A prior far wider than the
//! changes would add `k` degrees of freedom and nothing to the sum (shrinking `s0^2` by up to
//! `(m - n) / m`), where this one tends to `SSR / (m - r)`, as without a prior; a prior that holds
//! parameters tightly takes their degrees of freedom from the count, not the data's. The
//! prior's sigmas are scaled by `s0` with the data's (stated on the same footing as the
//! weights). Each parameter's [`ParameterUncertainty::data_share`] is the diagonal of the
//! resolution matrix `(J^T W J + P)^-1 J^T W J`, `1 - C_pp / s_p^2`: 1 when the data determine
//! it alone, 0 when the prior does.

use crate::error::{Error, Result};
use crate::identifiability::{analyze_core, analyze_from_r, Analysis, AnalysisOptions};
use crate::linalg::Matrix;
use crate::model::params::ParamId;
use crate::observe::Dataset;
use crate::solve::estimation::Calibration;

/// Changes below this many standard deviations are reported as within the noise.
pub(crate) const NOISE_SIGMAS: f64 = 2.0;

/// Correlations above this (in magnitude) are reported.
pub(crate) const HIGH_CORRELATION: f64 = 0.95;

/// One estimated parameter's uncertainty (file units).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ParameterUncertainty {
    /// The parameter.
    pub id: ParamId,
    /// Whether the data determines it individually.
    pub determined: bool,
    /// Its standard deviation (file units), when determined.
    pub sigma: Option<f64>,
    /// Its change from the starting value (file units).
    pub change: f64,
    /// `|change| / sigma`, when determined.
    pub significance: Option<f64>,
    /// The standard deviation of its prior (file units), when it has one.
    pub prior_sigma: Option<f64>,
    /// With a prior: the share of the data in its estimate, `1 - var_post / var_prior` on the
    /// unscaled information (the resolution matrix's diagonal): 1 when the data determine it,
    /// near 0 when only the prior does.
    pub data_share: Option<f64>,
    /// With a prior, what determines it (absent without a prior, or when it is not
    /// determined).
    pub determined_by: Option<DeterminedBy>,
}

/// What determines an estimate when the calibration has a prior.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum DeterminedBy {
    /// The data alone determine it individually (the prior only tightens it, giving at most
    /// 99 % of its information).
    Data,
    /// The data determine only combinations of it with others; the prior splits them.
    DataAndPrior,
    /// The prior alone: the data give less than [`PRIOR_ALONE_SHARE`] of its information (its
    /// [`ParameterUncertainty::data_share`]): none when no observation feels it, next to
    /// nothing when its prior is far tighter than what the data tell.
    Prior,
}

impl DeterminedBy {
    /// `data`, `data and prior`, `prior`.
    pub fn as_str(self) -> &'static str {
        match self {
            DeterminedBy::Data => "data",
            DeterminedBy::DataAndPrior => "data and prior",
            DeterminedBy::Prior => "prior",
        }
    }
}

/// A parameter whose data share is below this (1 %) is determined by the prior alone: its
/// posterior variance is within 1 % of its prior variance.
pub const PRIOR_ALONE_SHARE: f64 = 0.01;

/// A combination the data determines although its members are not (an identical group).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CombinationUncertainty {
    /// Members and coefficients (file units).
    pub terms: Vec<(ParamId, f64)>,
    /// Value after calibration.
    pub value: f64,
    /// Value before calibration.
    pub initial: f64,
    /// Standard deviation.
    pub sigma: f64,
    /// `|value - initial| / sigma`.
    pub significance: f64,
}

/// The uncertainty of a calibration.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Uncertainty {
    /// Variance factor `s0^2 = SSR / (m - r)` (with a prior, `SSR / (m - tr H_data)`: see the
    /// module documentation).
    pub variance_factor: f64,
    /// Degrees of freedom `m - r` (with a prior, the rows of the data and the prior less the
    /// rank: `m + k - r`).
    pub dof: usize,
    /// The data's redundancy the variance factor divides by: `m - r` without a prior, `m -
    /// tr H_data` with one (see the module documentation).
    pub redundancy: f64,
    /// Per estimated parameter.
    pub parameters: Vec<ParameterUncertainty>,
    /// Determined combinations of identically redundant groups (groups whose members also take
    /// part in other dependencies have no determined combination of their own and are left out).
    pub combinations: Vec<CombinationUncertainty>,
    /// Pairs of determined parameters correlated above [`HIGH_CORRELATION`].
    pub(crate) correlations: Vec<(ParamId, ParamId, f64)>,
    /// The identifiability analysis behind it (without the display-only parts: row labels,
    /// file-unit Jacobian and its singular values are empty; `identifiability::analyze` gives
    /// them).
    pub analysis: Analysis,
    /// Covariance of the estimated parameters in internal units over the determined directions.
    covariance: Vec<Vec<f64>>,
}

impl Uncertainty {
    /// Variance of `sum c_j p_j` with `c` over the estimated parameters in file units.
    fn variance_file(&self, cal: &Calibration, coefs: &[(ParamId, f64)]) -> f64 {
        let robot = &cal.calibrated;
        let idx: Vec<(usize, f64)> = coefs
            .iter()
            .filter_map(|&(id, c)| {
                let k = self.analysis.parameters.iter().position(|&p| p == id)?;
                Some((k, c / robot.units.factor(robot.param_quantity(id))))
            })
            .collect();
        idx.iter()
            .map(|&(a, ca)| {
                idx.iter()
                    .map(|&(b, cb)| ca * cb * self.covariance[a][b])
                    .sum::<f64>()
            })
            .sum()
    }

    /// The covariance of the estimated parameters in file units, in the order of
    /// [`Analysis::parameters`] (the calibration's `estimated`): entry `(a, b)` is in the unit
    /// of parameter `a` times the unit of parameter `b`. It is the covariance over the determined
    /// directions (`s0^2` times the pseudo-inverse of the information): a determined
    /// parameter's diagonal entry is its [`ParameterUncertainty::sigma`] squared; the entries of
    /// parameters determined only in combination mean something only in the combinations the
    /// data determines (`c^T C c` is the variance of `sum c_j p_j`, as for
    /// [`CombinationUncertainty::sigma`]).
    pub fn covariance_file(&self, robot: &crate::model::robot::Robot) -> Vec<Vec<f64>> {
        let f: Vec<f64> = self
            .analysis
            .parameters
            .iter()
            .map(|&id| robot.units.factor(robot.param_quantity(id)))
            .collect();
        self.covariance
            .iter()
            .zip(&f)
            .map(|(row, fa)| row.iter().zip(&f).map(|(c, fb)| c / (fa * fb)).collect())
            .collect()
    }

    /// The covariance of the estimated parameters in internal units (metres, radians, ...), in
    /// the order of [`Analysis::parameters`]: [`Uncertainty::covariance_file`] before its
    /// conversion to the file's units.
    pub fn covariance_internal(&self) -> &[Vec<f64>] {
        &self.covariance
    }

    /// The uncertainty of parameter `id`, if it was estimated.
    pub fn parameter(&self, id: ParamId) -> Option<&ParameterUncertainty> {
        self.parameters.iter().find(|p| p.id == id)
    }
}

/// Computes the uncertainty of `cal`, calibrated on `data`, with the Jacobian taken at
/// `nominal` (the design model, whose exact redundancies define what is determined; pass the
/// robot file the calibration started from when the solver started elsewhere).
pub fn uncertainty(
    cal: &Calibration,
    data: &Dataset,
    nominal: &crate::model::robot::Robot,
) -> Result<Uncertainty> {
    let opts = AnalysisOptions {
        weights: cal.options.weights,
        orientation: cal.options.orientation,
        prior: cal.options.prior.clone(),
        ..Default::default()
    };
    let analysis = analyze_core(nominal, data, &cal.estimated, &opts)?;
    from_analysis(cal, analysis)
}

/// [`uncertainty`] of a calibration on the data it was fitted to (`data` must be that data):
/// when `nominal` is the solver's start, the solver's first evaluation there (over the
/// estimated parameters, with the same weights) is the linearisation wanted, and no further
/// pass of forward kinematics is needed. This is what the workflow runs.
pub fn uncertainty_of_fit(
    cal: &Calibration,
    data: &Dataset,
    nominal: &crate::model::robot::Robot,
) -> Result<Uncertainty> {
    let ascending = cal.estimated.windows(2).all(|w| w[0] < w[1]);
    let opts = AnalysisOptions {
        weights: cal.options.weights,
        orientation: cal.options.orientation,
        prior: cal.options.prior.clone(),
        ..Default::default()
    };
    // Rows the fit weighed other than as stated (a model-error floor, a robust loss): the
    // information is that of the rows as the fit weighed them, as the objective that scales
    // it is (at the stated sigmas, a floor 40 times above them made every sigma 40 times too
    // small).
    if ascending && !unit_scale(&cal.row_scale) {
        let r = scaled_r(cal, data, nominal);
        return from_analysis(
            cal,
            analyze_from_r(nominal, data, &cal.estimated, &opts, &r)?,
        );
    }
    match &cal.start_r {
        Some(r) if ascending && nominal == &cal.initial => from_analysis(
            cal,
            analyze_from_r(nominal, data, &cal.estimated, &opts, r)?,
        ),
        _ => uncertainty(cal, data, nominal),
    }
}

/// Whether every row keeps the weight its standard deviation gives it (no floor, no robust
/// down-weighting).
fn unit_scale(row_scale: &[f64]) -> bool {
    row_scale.iter().all(|s| s.to_bits() == 1.0f64.to_bits())
}

/// The `R` of the QR of the data's weighted `[J | r]` at `nominal` over the calibration's
/// estimated parameters, each row also times its final row scale (the floor's and the robust
/// loss's): the rows as the fit weighed them. One pass of forward kinematics.
fn scaled_r(cal: &Calibration, data: &Dataset, nominal: &crate::model::robot::Robot) -> Matrix {
    use crate::linalg::{QrAccumulator, QR_BLOCK};
    let problem = crate::solve::problem::Problem::new(
        nominal,
        data,
        &cal.estimated,
        cal.options.weights,
        cal.options.orientation,
    )
    .with_row_scale(&cal.row_scale);
    let mut acc = QrAccumulator::new(problem.cols() + 1, QR_BLOCK);
    let mut res = vec![0.0; problem.rows()];
    problem.evaluate_qr(nominal, &mut res, &mut acc);
    let mut r = Matrix::zeros(0, 0);
    acc.r_into(&mut r);
    r
}

fn from_analysis(cal: &Calibration, analysis: Analysis) -> Result<Uncertainty> {
    let robot = &cal.calibrated;
    let (m, n, r) = (analysis.residuals, analysis.parameters.len(), analysis.rank);
    if m <= r {
        return Err(Error::NoDegreesOfFreedom {
            residuals: m,
            rank: r,
        });
    }
    let dof = m - r;
    // Covariance in internal units: s0^2 D^-1 V_r S_r^-2 V_r^T D^-1.
    let v = &analysis.right_singular_vectors;
    let s = &analysis.singular_values_scaled;
    let d = analysis.column_norms.clone();
    // The inverse information first (the resolution needs it unscaled), then times s0^2.
    let mut covariance = vec![vec![0.0; n]; n];
    for (a, row) in covariance.iter_mut().enumerate() {
        for (b, c) in row.iter_mut().enumerate() {
            if d[a] == 0.0 || d[b] == 0.0 {
                continue;
            }
            let sum: f64 = (0..r).map(|k| v[(a, k)] * v[(b, k)] / (s[k] * s[k])).sum();
            *c = sum / (d[a] * d[b]);
        }
    }
    let inverse_information: Vec<f64> = (0..n).map(|a| covariance[a][a]).collect();
    // The prior's sigmas (internal units) and the leverage of its rows, `C_kk / s_k^2`.
    let prior_sigma: Vec<Option<f64>> = analysis
        .parameters
        .iter()
        .map(|&id| cal.options.prior.sigma(&cal.initial, id))
        .collect();
    let prior_leverage: f64 = prior_sigma
        .iter()
        .zip(&inverse_information)
        .filter_map(|(s, c)| s.map(|s| (c / (s * s)).min(1.0)))
        .sum();
    // The data's redundancy: its rows less their leverage (the rank less the prior rows').
    let redundancy = (m - analysis.prior_rows) as f64 - (r as f64 - prior_leverage);
    if redundancy <= 0.5 {
        return Err(Error::NoDegreesOfFreedom {
            residuals: m - analysis.prior_rows,
            rank: r,
        });
    }
    let variance_factor = cal.objective_after / redundancy;
    for c in covariance.iter_mut().flatten() {
        *c *= variance_factor;
    }
    let with_prior = !cal.options.prior.is_empty();
    let mut u = Uncertainty {
        variance_factor,
        dof,
        redundancy,
        parameters: Vec::new(),
        combinations: Vec::new(),
        correlations: Vec::new(),
        analysis,
        covariance,
    };
    for (k, &id) in u.analysis.parameters.clone().iter().enumerate() {
        let determined = u.analysis.determined[k] && d[k] > 0.0;
        let f = robot.units.factor(robot.param_quantity(id));
        let sigma = determined.then(|| u.covariance[k][k].max(0.0).sqrt() / f);
        let change = robot.get_user(id) - cal.initial.get_user(id);
        let significance = sigma.map(|s| {
            if s > 0.0 {
                change.abs() / s
            } else {
                f64::INFINITY
            }
        });
        let prior = prior_sigma[k];
        let data_share = prior
            .filter(|_| determined)
            .map(|p| (1.0 - inverse_information[k] / (p * p)).clamp(0.0, 1.0));
        let determined_by = (with_prior && determined).then(|| {
            if data_share.is_some_and(|s| s < PRIOR_ALONE_SHARE) {
                DeterminedBy::Prior
            } else if u.analysis.determined_by_data[k] {
                DeterminedBy::Data
            } else {
                DeterminedBy::DataAndPrior
            }
        });
        u.parameters.push(ParameterUncertainty {
            id,
            determined,
            sigma,
            change,
            significance,
            prior_sigma: prior.map(|p| p / f),
            data_share,
            determined_by,
        });
    }
    for g in u
        .analysis
        .identical_groups
        .clone()
        .into_iter()
        .filter(|g| g.determined)
    {
        let sigma = u.variance_file(cal, &g.terms).max(0.0).sqrt();
        let initial: f64 = g
            .terms
            .iter()
            .map(|&(id, c)| c * cal.initial.get_user(id))
            .sum();
        let value: f64 = g.terms.iter().map(|&(id, c)| c * robot.get_user(id)).sum();
        let significance = if sigma > 0.0 {
            (value - initial).abs() / sigma
        } else {
            f64::INFINITY
        };
        u.combinations.push(CombinationUncertainty {
            terms: g.terms,
            value,
            initial,
            sigma,
            significance,
        });
    }
    for a in 0..n {
        for b in a + 1..n {
            if !(u.parameters[a].determined && u.parameters[b].determined) {
                continue;
            }
            let denom = (u.covariance[a][a] * u.covariance[b][b]).sqrt();
            if denom > 0.0 {
                let rho = u.covariance[a][b] / denom;
                if rho.abs() > HIGH_CORRELATION {
                    u.correlations
                        .push((u.parameters[a].id, u.parameters[b].id, rho));
                }
            }
        }
    }
    Ok(u)
}
