//! How rows that carry standard deviations of their own are weighted: a staged start when the
//! stated precisions differ by orders of magnitude, and a model-error floor when the rows'
//! residuals show more than their instrument's noise.
//!
//! **Staged start.** Rows stated 10^3 times more precise than the others (points "anchored" at
//! 0.001 mm among rows weighted at 1 mm) make the objective a narrow curved valley: a solver
//! started far from the answer crawls along it for hundreds of iterations, or stops in a
//! corner of it where the model degenerates. When, among the rows of a quantity (lengths or
//! angles), the smallest standard deviation is below [`STAGE_RATIO`] times the median, the fit
//! first runs with every standard deviation of that quantity raised to at least the median (the
//! weights of the rows alike made uniform), and the fit at the stated standard deviations starts
//! from where that one ends: a continuation from uniform weights to the stated ones.
//!
//! **Model-error floor.** A tracker's standard deviation covers the instrument, not the model:
//! where the model cannot fit the robot to the instrument's precision, rows weighted by it alone
//! let a few points stated most precise dominate the fit. Each row with a standard deviation of
//! its own (`sigma_position`, `sigma_x..z`, `sigma_angle`) is then weighted by `1 / max(s_i,
//! m)`, `m` the model error of its quantity, estimated from the residuals so that `sum e_i^2 /
//! max(s_i, m)^2` over those rows equals their share of the degrees of freedom, `n_q (N - p) /
//! N` (`N` residuals, `p` estimated parameters: the average leverage `p / N` taken off each
//! row). No row is trusted beyond what the model reproduces: a row stated more precise than
//! `m` counts as `m`, a row stated less precise keeps its own deviation. The floor is estimated
//! only when the rows' residuals exceed their stated standard deviations significantly (the
//! chi-square of the rows above its mean by three of its standard deviations, `n + 3 sqrt(2
//! n)`), and re-estimated after each refit until it changes by less than 2 % (at most
//! [`FLOOR_ROUNDS`] refits), for each quantity whose rows failed that test (the others keep a
//! floor of 0). The floored fit is kept when the residuals' likelihood under `max(s_i, m)^2`,
//! charged 2 per floored quantity (Akaike's criterion), beats the stated fit's under `s_i^2`; a
//! stated fit stopped at its probe's cap ([`STATED_PROBE`]) is finished before it loses. Rows
//! whose residuals match their standard deviations are left as stated: precise anchors that
//! the model fits keep their weight. Rows without a standard deviation of their own are
//! weighted by the default weights as stated, always. The degrees of freedom take the average
//! leverage `p / N` off every row: rows stated far more precise than the rest have more, so
//! the floor errs low for them (towards the stated sigmas).
//!
//! **Why a bound and not a sum.** The "virtual noise" of Tenhumberg and Bauml adds `m` in
//! quadrature, `sqrt(s_i^2 + m^2)`, as independent errors add. Where every stated deviation is
//! far below `m`, as a tracker's are beside a geometric model's error, that sum weighs the rows
//! within `1 + max s_i^2 / m^2` of uniform (4 % on the IPA UR10's series C): a tilt by the
//! instrument's noise where the error is the model's, which moved the fit by a few hundredths
//! of its standard errors to either side of the unweighted fit as the data fell (held out on the
//! IPA UR10: 0.0003 mm worse on C -> A, 0.0017 mm better on D -> C). The bound makes such rows'
//! weights uniform, so sigma columns below the model error give exactly the fit without them,
//! and it acts only on rows whose stated deviation exceeds the model error, where the
//! instrument's noise is what the row's error is made of. Its price, on synthetic arms with an
//! unmodelled error and tracker-like sigmas drawn as the sum assumes (`scripts/
//! weighting-study.py`): 0.02-0.2 % more held-out error than the sum on average, behind it in
//! 44 of 70 data sets; docs/calibrate.md gives the figures.

use crate::observe::{Dataset, RowQuantity};

/// A quantity's smallest stated standard deviation below this fraction of its median starts the
/// fit from uniform weights (see the module documentation).
pub const STAGE_RATIO: f64 = 1e-2;

/// The most iterations of the fit at the stated standard deviations before it is weighed against
/// the floored fit (continued to the cap when it wins).
pub const STATED_PROBE: usize = 25;

/// The most refits the model-error floor makes.
pub const FLOOR_ROUNDS: usize = 6;

/// How rows with standard deviations of their own are weighted (in a calibration spec:
/// `model_error = "auto"` or `"none"`).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum ModelErrorMode {
    /// Each row by `max(sigma, m)`, with the model error `m` of its quantity estimated from the
    /// residuals when they show more than the stated sigmas (0 otherwise).
    #[default]
    Auto,
    /// Each row by its stated standard deviation alone.
    None,
}

/// The model error below which the fit raised the rows' own standard deviations, per quantity
/// (internal units: m, rad; 0 where the rows' residuals matched their standard deviations).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModelErrorFloor {
    /// The least standard deviation a length row with its own is weighted by (m).
    pub length: f64,
    /// The least standard deviation an angle row with its own is weighted by (rad).
    pub angle: f64,
    /// Rows with a standard deviation of their own, per quantity (lengths, angles).
    pub rows: [usize; 2],
    /// Fits run with a floor (each one from the last one's answer).
    pub refits: usize,
}

impl ModelErrorFloor {
    /// The floor of `quantity`.
    pub fn of(&self, quantity: RowQuantity) -> f64 {
        match quantity {
            RowQuantity::Length => self.length,
            RowQuantity::Angle => self.angle,
            // A camera's pixels keep their stated deviations: a detector's sigma is about the
            // corners it found, and the lens is fitted with the robot.
            RowQuantity::Pixel => 0.0,
        }
    }
}

/// The quantities in [`spread`]'s order.
const QUANTITIES: [RowQuantity; 3] = [RowQuantity::Length, RowQuantity::Angle, RowQuantity::Pixel];

fn slot(q: RowQuantity) -> usize {
    match q {
        RowQuantity::Length => 0,
        RowQuantity::Angle => 1,
        RowQuantity::Pixel => 2,
    }
}

/// Per row of `data`: its quantity, and whether it carries a standard deviation of its own.
pub(crate) fn row_kinds(data: &Dataset) -> Vec<(RowQuantity, bool)> {
    let mut out = Vec::with_capacity(data.rows());
    for o in &data.observations {
        for (k, row) in o.rows().iter().enumerate() {
            out.push((row.quantity, o.sigma(k).is_some()));
        }
    }
    out
}

/// The rows of `data` with a standard deviation of their own, and how many of them state one
/// above `floor` (those keep it; the others are weighted by the floor alike), over lengths
/// and angles together (pixels keep theirs and are not counted).
pub(crate) fn rows_above_floor(data: &Dataset, floor: &ModelErrorFloor) -> (usize, usize) {
    let (mut own, mut above) = (0, 0);
    for o in &data.observations {
        for (k, row) in o.rows().iter().enumerate() {
            if let (Some(s), false) = (o.sigma(k), row.quantity == RowQuantity::Pixel) {
                own += 1;
                above += usize::from(s > floor.of(row.quantity));
            }
        }
    }
    (own, above)
}

/// The row scale of the staged start (see the module documentation), or `None` when no
/// quantity's standard deviations spread that far.
pub(crate) fn staged_scale(kinds: &[(RowQuantity, bool)], sigma: &[f64]) -> Option<Vec<f64>> {
    let spread = spread(kinds, sigma);
    let staged = spread
        .iter()
        .any(|&(smallest, median)| smallest < STAGE_RATIO * median);
    staged.then(|| {
        kinds
            .iter()
            .zip(sigma)
            .map(|(&(q, _), &s)| s / s.max(spread[slot(q)].1))
            .collect()
    })
}

/// The staged start's row scale when the sigmas do not spread far: every row of a quantity at
/// its median standard deviation (uniform weights, as the floor's first estimate needs them).
pub(crate) fn uniform_scale(kinds: &[(RowQuantity, bool)], sigma: &[f64]) -> Vec<f64> {
    let spread = spread(kinds, sigma);
    kinds
        .iter()
        .zip(sigma)
        .map(|(&(q, _), &s)| s / spread[slot(q)].1)
        .collect()
}

/// Per quantity (lengths, angles, pixels), the smallest and the median standard deviation of
/// its rows (0 and 0 without rows).
fn spread(kinds: &[(RowQuantity, bool)], sigma: &[f64]) -> [(f64, f64); 3] {
    QUANTITIES.map(|q| {
        let mut s: Vec<f64> = kinds
            .iter()
            .zip(sigma)
            .filter(|((k, _), _)| *k == q)
            .map(|(_, &s)| s)
            .collect();
        // The smallest and the element a sort would put at the middle, found in linear time.
        let Some(lo) = s.iter().copied().min_by(f64::total_cmp) else {
            return (0.0, 0.0);
        };
        let mid = s.len() / 2;
        let (_, median, _) = s.select_nth_unstable_by(mid, f64::total_cmp);
        (lo, *median)
    })
}

/// The negative log-likelihood (up to a constant) of the weighted residuals `r` (`e_i / s_i`)
/// when each row with its own standard deviation has variance `v_i = max(s_i, m)^2`: `sum
/// e_i^2 / v_i + ln v_i` over those rows, plus `r_i^2` over the others (whose variance is
/// fixed). The lower of two fits by it is the one the residuals favour.
pub(crate) fn likelihood_cost(
    kinds: &[(RowQuantity, bool)],
    sigma: &[f64],
    r: &[f64],
    floor: &ModelErrorFloor,
) -> f64 {
    kinds
        .iter()
        .zip(sigma)
        .zip(r)
        .map(|((&(q, own), &s), &ri)| {
            if own {
                let v = s.max(floor.of(q)).powi(2);
                (ri * s).powi(2) / v + v.ln()
            } else {
                ri * ri
            }
        })
        .sum()
}

/// The model error per quantity from the weighted residuals `r` (`r_i = e_i / s_i`) of the rows
/// `kinds` at standard deviations `sigma`, with `dof_fraction = (N - p) / N`; `first` applies
/// the significance test (a floor is started only when the residuals demand one). `None` for a
/// quantity without rows of its own.
pub(crate) fn estimate_floor(
    kinds: &[(RowQuantity, bool)],
    sigma: &[f64],
    r: &[f64],
    dof_fraction: f64,
    first: bool,
) -> [Option<f64>; 2] {
    let mut out = [None; 2];
    for q in [RowQuantity::Length, RowQuantity::Angle] {
        // Raw residuals and stated standard deviations of the rows of q with their own.
        let rows: Vec<(f64, f64)> = kinds
            .iter()
            .zip(sigma)
            .zip(r)
            .filter(|(((k, own), _), _)| *k == q && *own)
            .map(|((_, &s), &ri)| (ri * s, s))
            .filter(|(e, s)| e.is_finite() && s.is_finite())
            .collect();
        if rows.is_empty() {
            continue;
        }
        let n = rows.len() as f64;
        let dof = (n * dof_fraction).max(1.0);
        let chi = |m: f64| {
            rows.iter()
                .map(|(e, s)| (e / s.max(m)).powi(2))
                .sum::<f64>()
        };
        let chi0 = chi(0.0);
        if chi0 <= dof || (first && chi0 <= dof + 3.0 * (2.0 * dof).sqrt()) {
            out[slot(q)] = Some(0.0);
            continue;
        }
        // chi is non-increasing in m (strictly above the smallest s, where it crosses dof, as
        // chi(0) > dof); at hi = sqrt(sum e^2 / dof) every max(s, hi) >= hi, so chi(hi) <= dof.
        let mut lo = 0.0;
        let mut hi = (rows.iter().map(|(e, _)| e * e).sum::<f64>() / dof).sqrt();
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if chi(mid) > dof {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= 1e-12 * hi {
                break;
            }
        }
        out[slot(q)] = Some(hi);
    }
    out
}

/// The row scale of a floor: `s_i / max(s_i, m)` for the rows with their own standard
/// deviation, 1 for the others.
pub(crate) fn floor_scale(
    kinds: &[(RowQuantity, bool)],
    sigma: &[f64],
    floor: &ModelErrorFloor,
) -> Vec<f64> {
    kinds
        .iter()
        .zip(sigma)
        .map(|(&(q, own), &s)| {
            let m = floor.of(q);
            if own && m > 0.0 {
                s / s.max(m)
            } else {
                1.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Residuals drawn as `e_i ~ N(0, max(s_i, m)^2)` with sigmas spread over more than two
    /// orders of magnitude, a fifth of them above `m`: the estimate recovers `m` to 5 % (4,000
    /// rows: the chi-square's relative spread is about 2 %), the rows below `m` weigh alike and
    /// the others keep their own, and residuals drawn at the stated sigmas give no floor.
    #[test]
    fn the_floor_recovers_the_model_error_the_residuals_carry() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let n = 4000;
        let m = 3e-4;
        let kinds = vec![(RowQuantity::Length, true); n];
        // 1e-6 .. 3.85e-4 m in steps of 4e-6: 22 of the 97 values above m.
        let sigma: Vec<f64> = (0..n).map(|i| 1e-6 + 4e-6 * (i % 97) as f64).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut z = || -> f64 { StandardNormal.sample(&mut rng) };
        let r_model: Vec<f64> = (0..n).map(|i| z() * sigma[i].max(m) / sigma[i]).collect();
        let [got, _] = estimate_floor(&kinds, &sigma, &r_model, 1.0, true);
        let got = got.unwrap();
        assert!((got - m).abs() < 0.05 * m, "{got} vs {m}");
        // The rows below the floor weigh alike (their scaled residuals are e_i / m), the rest
        // keep their own deviation.
        let floor = ModelErrorFloor {
            length: got,
            ..ModelErrorFloor::default()
        };
        let scale = floor_scale(&kinds, &sigma, &floor);
        for (&s, &k) in sigma.iter().zip(&scale) {
            let want = if s < got { s / got } else { 1.0 };
            assert_eq!(k.to_bits(), want.to_bits(), "sigma {s}");
        }
        let r_stated: Vec<f64> = (0..n).map(|_| z()).collect();
        let [none, angle] = estimate_floor(&kinds, &sigma, &r_stated, 1.0, true);
        assert_eq!(none, Some(0.0));
        assert_eq!(angle, None);
    }

    /// Each quantity's smallest and middle standard deviation are a sorted copy's first and
    /// middle elements, to the bit, with ties and with a quantity that has no rows.
    #[test]
    fn the_spread_is_that_of_the_sorted_sigmas() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for n in [0, 1, 2, 3, 10, 101, 2000] {
            let kinds: Vec<(RowQuantity, bool)> = (0..n)
                .map(|_| (QUANTITIES[rng.random_range(0..2)], true))
                .collect();
            // Sigmas from a few values: many ties.
            let sigma: Vec<f64> = (0..n)
                .map(|_| 1e-4 * f64::from(rng.random_range(1..20u8)))
                .collect();
            let got = spread(&kinds, &sigma);
            for (q, (lo, mid)) in QUANTITIES.iter().zip(got) {
                let mut s: Vec<f64> = kinds
                    .iter()
                    .zip(&sigma)
                    .filter(|((k, _), _)| k == q)
                    .map(|(_, &s)| s)
                    .collect();
                s.sort_by(f64::total_cmp);
                let want = s.first().map_or((0.0, 0.0), |&l| (l, s[s.len() / 2]));
                assert_eq!(
                    (lo.to_bits(), mid.to_bits()),
                    (want.0.to_bits(), want.1.to_bits()),
                    "{q:?}, {n} rows"
                );
            }
        }
    }

    /// A spread of 1000 between anchors and the rest stages the start; a spread of 50 does not.
    #[test]
    fn a_thousandfold_spread_of_sigmas_stages_the_start() {
        let mut kinds = vec![(RowQuantity::Length, false); 100];
        let mut sigma = vec![1e-3; 100];
        for k in 0..5 {
            kinds[k].1 = true;
            sigma[k] = 1e-6;
        }
        let scale = staged_scale(&kinds, &sigma).expect("staged");
        assert!((scale[0] - 1e-3).abs() < 1e-15 && scale[50].to_bits() == 1f64.to_bits());
        sigma[..5].fill(2e-5);
        assert!(staged_scale(&kinds, &sigma).is_none());
    }
}
