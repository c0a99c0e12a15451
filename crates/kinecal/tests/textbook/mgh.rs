//! The Moré-Garbow-Hillstrom nonlinear least-squares test problems.
//!
//! Reference: J. J. Moré, B. S. Garbow and K. E. Hillstrom, "Testing unconstrained
//! optimization software", ACM Transactions on Mathematical Software 7(1), 1981, 17-41
//! (problems (1)-(35) of section 3), and the Fortran test set that accompanies it in
//! MINPACK-1 (`ssqfcn`/`ssqjac`/`initpt` and the `lmder` driver with its data file
//! `ssq.data`; `objfcn`/`umipt` and `um.data` for the unconstrained-minimisation driver;
//! `vecfcn` for the nonlinear-equation problems).
//!
//! Conventions:
//! - Every problem is a set of `m` residuals `r_i(x)` of `n` unknowns, and the objective is
//!   `f(x) = sum_i r_i(x)^2` (no factor 1/2), as in the paper.
//! - Indices in the comments are 1-based, as in the paper; the code is 0-based.
//! - The Jacobian is `J[i][j] = d r_i / d x_j`, stored row-major (`j[i * n + k]`), analytic.
//! - Sizes: the problems that MINPACK's `lmder` test driver runs are given at the sizes of
//!   its data file, and from `x0`, `10 x0`, `100 x0` where the driver uses those (the extra
//!   starts are separate entries named "..., 10 x0" / "..., 100 x0", with the same minima).
//!   As in MINPACK's `initpt`, Watson's `x0` is zero, so its "10 x0" / "100 x0" starts are
//!   `x_j = 10` / `x_j = 100`. The remaining problems are given once, from `x0`, at the
//!   sizes of the paper / MINPACK's unconstrained-minimisation data (Gulf m = 99,
//!   Biggs m = 13, n = 10 or 12 for the variable-size ones).
//! - `minima` lists, in ascending order, the values of `f` at the minima reported in the
//!   paper for that (m, n), and other known local values. Where the paper gives six digits
//!   and "...", the value here is the same minimum to more digits, recomputed to
//!   convergence and checked against the paper's digits, against the final norms printed by
//!   MINPACK's `lmder` driver (see the tests) and, where available, against the values in
//!   Moré and Wild's (2009) benchmark data. Values reached only "at infinity" (Bard,
//!   Kowalik-Osborne) are infima approached with diverging parameters. Two listed values
//!   are stationary points, not minima, listed because the literature or MINPACK's runs stop
//!   there: Biggs EXP6 5.65565e-3 (the paper's value; a saddle) and Chebyquad n = 1, m = 8 at
//!   x0 (a local maximum). Local values "found here" are documented at each problem.
//! - (35) Chebyquad is included as well, because MINPACK's `lmder` driver runs it.
#![allow(dead_code)]

use std::f64::consts::PI;

/// One MGH least-squares problem: residuals r(x) (m of them) of n unknowns.
#[allow(clippy::type_complexity)]
pub struct Mgh {
    /// Name and number as in MGH 1981 (e.g. "(1) Rosenbrock").
    pub name: String,
    /// Number of residuals.
    pub m: usize,
    /// Number of unknowns.
    pub n: usize,
    /// r(x) into r (len m).
    pub residuals: Box<dyn Fn(&[f64], &mut [f64]) + Send + Sync>,
    /// The Jacobian dr_i/dx_j, row-major m x n, into j (len m*n). Analytic.
    pub jacobian: Box<dyn Fn(&[f64], &mut [f64]) + Send + Sync>,
    /// The standard starting point x0 of the paper (10 x0 or 100 x0 in the entries so named).
    pub start: Vec<f64>,
    /// The minimum value of f = sum r^2 reported in the literature for this (m, n), with
    /// the paper's value; for problems with several local minima, all known values.
    pub minima: Vec<f64>,
    /// The minimiser when known in closed form (for checks), else None.
    pub minimiser: Option<Vec<f64>>,
}

/// The problems, each at the sizes MINPACK's test driver uses (and, like MINPACK's driver,
/// also from the starting points 10*x0 and 100*x0 where the driver uses those, as separate
/// entries named e.g. "(1) Rosenbrock, 10 x0" with the same known minima).
pub fn problems() -> Vec<Mgh> {
    let mut v = Vec::new();
    let one = &[1][..];
    let three = &[1, 10, 100][..];
    starts(&mut v, three, rosenbrock);
    starts(&mut v, three, freudenstein_roth);
    starts(&mut v, one, powell_badly_scaled);
    starts(&mut v, one, brown_badly_scaled);
    starts(&mut v, one, beale);
    starts(&mut v, one, || jennrich_sampson(10));
    starts(&mut v, three, helical_valley);
    starts(&mut v, three, bard);
    starts(&mut v, one, gaussian);
    starts(&mut v, &[1, 10], meyer);
    starts(&mut v, one, || gulf(99));
    starts(&mut v, one, || box_3d(10));
    starts(&mut v, three, powell_singular);
    starts(&mut v, one, wood);
    starts(&mut v, three, kowalik_osborne);
    starts(&mut v, three, || brown_dennis(20));
    starts(&mut v, one, osborne_1);
    starts(&mut v, one, || biggs_exp6(13));
    starts(&mut v, one, osborne_2);
    for n in [6, 9, 12] {
        starts(&mut v, three, move || watson(n));
    }
    starts(&mut v, one, || extended_rosenbrock(10));
    starts(&mut v, one, || extended_powell(12));
    starts(&mut v, one, || penalty_1(10));
    starts(&mut v, one, || penalty_2(10));
    starts(&mut v, one, || variably_dimensioned(10));
    starts(&mut v, one, || trigonometric(10));
    starts(&mut v, three, || brown_almost_linear(10));
    starts(&mut v, one, || brown_almost_linear(30));
    starts(&mut v, one, || brown_almost_linear(40));
    starts(&mut v, one, || discrete_boundary_value(10));
    starts(&mut v, one, || discrete_integral_equation(10));
    starts(&mut v, one, || broyden_tridiagonal(10));
    starts(&mut v, one, || broyden_banded(10));
    for m in [10, 50] {
        starts(&mut v, one, move || linear_full_rank(5, m));
    }
    for m in [10, 50] {
        starts(&mut v, one, move || linear_rank_1(5, m));
    }
    for m in [10, 50] {
        starts(&mut v, one, move || linear_rank_1_zero(5, m));
    }
    starts(&mut v, three, || chebyquad(1, 8));
    for n in [8, 9, 10] {
        starts(&mut v, one, move || chebyquad(n, n));
    }
    v
}

// ----------------------------------------------------------------------------------------
// Helpers.

type Fun = Box<dyn Fn(&[f64], &mut [f64]) + Send + Sync>;

/// f(x) = sum r_i(x)^2.
fn sum_sq(p: &Mgh, x: &[f64]) -> f64 {
    let mut r = vec![0.0; p.m];
    (p.residuals)(x, &mut r);
    r.iter().map(|v| v * v).sum()
}

#[allow(clippy::too_many_arguments)]
fn mgh(
    name: String,
    m: usize,
    n: usize,
    residuals: impl Fn(&[f64], &mut [f64]) + Send + Sync + 'static,
    jacobian: impl Fn(&[f64], &mut [f64]) + Send + Sync + 'static,
    start: Vec<f64>,
    minima: Vec<f64>,
    minimiser: Option<Vec<f64>>,
) -> Mgh {
    let residuals: Fun = Box::new(residuals);
    let jacobian: Fun = Box::new(jacobian);
    Mgh {
        name,
        m,
        n,
        residuals,
        jacobian,
        start,
        minima,
        minimiser,
    }
}

/// Pushes `make()` once per factor; factor k != 1 scales the start and adds ", k x0" to
/// the name. As MINPACK's `initpt` does for Watson, an all-zero x0 becomes x_j = k.
fn starts(out: &mut Vec<Mgh>, factors: &[u32], make: impl Fn() -> Mgh) {
    for &factor in factors {
        let mut p = make();
        if factor != 1 {
            p.name = format!("{}, {factor} x0", p.name);
            let k = f64::from(factor);
            if p.start.iter().all(|&s| s == 0.0) {
                p.start.iter_mut().for_each(|s| *s = k);
            } else {
                p.start.iter_mut().for_each(|s| *s *= k);
            }
        }
        out.push(p);
    }
}

fn zero(j: &mut [f64]) {
    j.iter_mut().for_each(|v| *v = 0.0);
}

// ----------------------------------------------------------------------------------------
// (1)-(35).

/// (1) Rosenbrock, m = n = 2. f = 0 at (1, 1).
fn rosenbrock() -> Mgh {
    mgh(
        "(1) Rosenbrock".into(),
        2,
        2,
        |x, r| {
            r[0] = 10.0 * (x[1] - x[0] * x[0]);
            r[1] = 1.0 - x[0];
        },
        |x, j| {
            j[0] = -20.0 * x[0];
            j[1] = 10.0;
            j[2] = -1.0;
            j[3] = 0.0;
        },
        vec![-1.2, 1.0],
        vec![0.0],
        Some(vec![1.0, 1.0]),
    )
}

/// (2) Freudenstein and Roth, m = n = 2. f = 0 at (5, 4); f = 48.9842... at
/// (11.41..., -0.8968...).
fn freudenstein_roth() -> Mgh {
    mgh(
        "(2) Freudenstein and Roth".into(),
        2,
        2,
        |x, r| {
            r[0] = -13.0 + x[0] + ((5.0 - x[1]) * x[1] - 2.0) * x[1];
            r[1] = -29.0 + x[0] + ((x[1] + 1.0) * x[1] - 14.0) * x[1];
        },
        |x, j| {
            j[0] = 1.0;
            j[1] = (10.0 - 3.0 * x[1]) * x[1] - 2.0;
            j[2] = 1.0;
            j[3] = (3.0 * x[1] + 2.0) * x[1] - 14.0;
        },
        vec![0.5, -2.0],
        vec![0.0, 48.984_253_679_240_01],
        Some(vec![5.0, 4.0]),
    )
}

/// (3) Powell badly scaled, m = n = 2. f = 0 at (1.098...e-5, 9.106...).
fn powell_badly_scaled() -> Mgh {
    mgh(
        "(3) Powell badly scaled".into(),
        2,
        2,
        |x, r| {
            r[0] = 1e4 * x[0] * x[1] - 1.0;
            r[1] = (-x[0]).exp() + (-x[1]).exp() - 1.0001;
        },
        |x, j| {
            j[0] = 1e4 * x[1];
            j[1] = 1e4 * x[0];
            j[2] = -(-x[0]).exp();
            j[3] = -(-x[1]).exp();
        },
        vec![0.0, 1.0],
        vec![0.0],
        None,
    )
}

/// (4) Brown badly scaled, n = 2, m = 3. f = 0 at (1e6, 2e-6).
fn brown_badly_scaled() -> Mgh {
    mgh(
        "(4) Brown badly scaled".into(),
        3,
        2,
        |x, r| {
            r[0] = x[0] - 1e6;
            r[1] = x[1] - 2e-6;
            r[2] = x[0] * x[1] - 2.0;
        },
        |x, j| {
            j[0] = 1.0;
            j[1] = 0.0;
            j[2] = 0.0;
            j[3] = 1.0;
            j[4] = x[1];
            j[5] = x[0];
        },
        vec![1.0, 1.0],
        vec![0.0],
        Some(vec![1e6, 2e-6]),
    )
}

/// (5) Beale, n = 2, m = 3: r_i = y_i - x1 (1 - x2^i). f = 0 at (3, 0.5).
fn beale() -> Mgh {
    const Y: [f64; 3] = [1.5, 2.25, 2.625];
    mgh(
        "(5) Beale".into(),
        3,
        2,
        |x, r| {
            for i in 0..3 {
                r[i] = Y[i] - x[0] * (1.0 - x[1].powi(i as i32 + 1));
            }
        },
        |x, j| {
            for i in 0..3 {
                let p = i as i32 + 1;
                j[2 * i] = -(1.0 - x[1].powi(p));
                j[2 * i + 1] = x[0] * p as f64 * x[1].powi(p - 1);
            }
        },
        vec![1.0, 1.0],
        vec![0.0],
        Some(vec![3.0, 0.5]),
    )
}

/// (6) Jennrich and Sampson, n = 2: r_i = 2 + 2i - (exp(i x1) + exp(i x2)).
/// f = 124.362... at x1 = x2 = 0.2578... for m = 10.
fn jennrich_sampson(m: usize) -> Mgh {
    assert_eq!(m, 10, "the literature minimum below is for m = 10");
    mgh(
        format!("(6) Jennrich and Sampson, m={m}"),
        m,
        2,
        move |x, r| {
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                let t = (i + 1) as f64;
                *ri = 2.0 + 2.0 * t - (t * x[0]).exp() - (t * x[1]).exp();
            }
        },
        move |x, j| {
            for i in 0..m {
                let t = (i + 1) as f64;
                j[2 * i] = -t * (t * x[0]).exp();
                j[2 * i + 1] = -t * (t * x[1]).exp();
            }
        },
        vec![0.3, 0.4],
        vec![124.362_182_355_614_8],
        None,
    )
}

/// theta of the helical valley: atan(x2/x1)/(2 pi) (+ 1/2 if x1 < 0); at x1 = 0,
/// sign(x2) / 4, as in MINPACK.
fn helix_theta(x1: f64, x2: f64) -> f64 {
    if x1 > 0.0 {
        (x2 / x1).atan() / (2.0 * PI)
    } else if x1 < 0.0 {
        (x2 / x1).atan() / (2.0 * PI) + 0.5
    } else {
        0.25_f64.copysign(x2)
    }
}

/// (7) Helical valley, m = n = 3. f = 0 at (1, 0, 0).
fn helical_valley() -> Mgh {
    mgh(
        "(7) Helical valley".into(),
        3,
        3,
        |x, r| {
            let th = helix_theta(x[0], x[1]);
            r[0] = 10.0 * (x[2] - 10.0 * th);
            r[1] = 10.0 * ((x[0] * x[0] + x[1] * x[1]).sqrt() - 1.0);
            r[2] = x[2];
        },
        |x, j| {
            let rho2 = x[0] * x[0] + x[1] * x[1];
            let rho = rho2.sqrt();
            // d theta / d x1 = -x2 / (2 pi rho^2), d theta / d x2 = x1 / (2 pi rho^2).
            j[0] = 100.0 * x[1] / (2.0 * PI * rho2);
            j[1] = -100.0 * x[0] / (2.0 * PI * rho2);
            j[2] = 10.0;
            j[3] = 10.0 * x[0] / rho;
            j[4] = 10.0 * x[1] / rho;
            j[5] = 0.0;
            j[6] = 0.0;
            j[7] = 0.0;
            j[8] = 1.0;
        },
        vec![-1.0, 0.0, 0.0],
        vec![0.0],
        Some(vec![1.0, 0.0, 0.0]),
    )
}

/// (8) Bard, n = 3, m = 15: r_i = y_i - (x1 + u_i / (v_i x2 + w_i x3)), u_i = i,
/// v_i = 16 - i, w_i = min(u_i, v_i). f = 8.21487...e-3; f = 17.4286... at
/// (0.8406..., -inf, -inf): an infimum, sum (y_i - mean y)^2 with x1 = mean y.
fn bard() -> Mgh {
    const Y: [f64; 15] = [
        0.14, 0.18, 0.22, 0.25, 0.29, 0.32, 0.35, 0.39, 0.37, 0.58, 0.73, 0.96, 1.34, 2.10, 4.39,
    ];
    fn uvw(i: usize) -> (f64, f64, f64) {
        let u = (i + 1) as f64;
        let v = (15 - i) as f64;
        (u, v, u.min(v))
    }
    mgh(
        "(8) Bard".into(),
        15,
        3,
        |x, r| {
            for i in 0..15 {
                let (u, v, w) = uvw(i);
                r[i] = Y[i] - (x[0] + u / (v * x[1] + w * x[2]));
            }
        },
        |x, j| {
            for i in 0..15 {
                let (u, v, w) = uvw(i);
                let d = v * x[1] + w * x[2];
                j[3 * i] = -1.0;
                j[3 * i + 1] = u * v / (d * d);
                j[3 * i + 2] = u * w / (d * d);
            }
        },
        vec![1.0, 1.0, 1.0],
        vec![8.214_877_306_578_97e-3, 17.428_693_333_333_33],
        None,
    )
}

/// (9) Gaussian, n = 3, m = 15: r_i = x1 exp(-x2 (t_i - x3)^2 / 2) - y_i, t_i = (8 - i)/2.
/// f = 1.12793...e-8.
fn gaussian() -> Mgh {
    const Y: [f64; 15] = [
        0.0009, 0.0044, 0.0175, 0.0540, 0.1295, 0.2420, 0.3521, 0.3989, 0.3521, 0.2420, 0.1295,
        0.0540, 0.0175, 0.0044, 0.0009,
    ];
    mgh(
        "(9) Gaussian".into(),
        15,
        3,
        |x, r| {
            for i in 0..15 {
                let t = (7.0 - i as f64) / 2.0;
                let d = t - x[2];
                r[i] = x[0] * (-0.5 * x[1] * d * d).exp() - Y[i];
            }
        },
        |x, j| {
            for i in 0..15 {
                let t = (7.0 - i as f64) / 2.0;
                let d = t - x[2];
                let e = (-0.5 * x[1] * d * d).exp();
                j[3 * i] = e;
                j[3 * i + 1] = -0.5 * x[0] * e * d * d;
                j[3 * i + 2] = x[0] * e * x[1] * d;
            }
        },
        vec![0.4, 1.0, 0.0],
        vec![1.127_932_769_62e-8],
        None,
    )
}

/// (10) Meyer, n = 3, m = 16: r_i = x1 exp(x2 / (t_i + x3)) - y_i, t_i = 45 + 5i.
/// f = 87.9458...
fn meyer() -> Mgh {
    const Y: [f64; 16] = [
        34780.0, 28610.0, 23650.0, 19630.0, 16370.0, 13720.0, 11540.0, 9744.0, 8261.0, 7030.0,
        6005.0, 5147.0, 4427.0, 3820.0, 3307.0, 2872.0,
    ];
    mgh(
        "(10) Meyer".into(),
        16,
        3,
        |x, r| {
            for i in 0..16 {
                let t = 45.0 + 5.0 * (i + 1) as f64;
                r[i] = x[0] * (x[1] / (t + x[2])).exp() - Y[i];
            }
        },
        |x, j| {
            for i in 0..16 {
                let t = 45.0 + 5.0 * (i + 1) as f64;
                let d = t + x[2];
                let e = (x[1] / d).exp();
                j[3 * i] = e;
                j[3 * i + 1] = x[0] * e / d;
                j[3 * i + 2] = -x[0] * e * x[1] / (d * d);
            }
        },
        vec![0.02, 4000.0, 250.0],
        vec![87.945_855_170_395_83],
        None,
    )
}

/// (11) Gulf research and development, n = 3, n <= m <= 100:
/// r_i = exp(-|y_i - x2|^x3 / x1) - t_i, t_i = i/100, y_i = 25 + (-50 ln t_i)^(2/3).
/// (The paper prints "|y_i m i x2|", a misprint for y_i - x2, as MINPACK has it.)
/// f = 0 at (50, 25, 1.5) for every m. MINPACK's unconstrained driver uses m = 99.
fn gulf(m: usize) -> Mgh {
    assert!((3..=100).contains(&m));
    let yt = move |i: usize| {
        let t = (i + 1) as f64 / 100.0;
        (25.0 + (-50.0 * t.ln()).powf(2.0 / 3.0), t)
    };
    mgh(
        format!("(11) Gulf research and development, m={m}"),
        m,
        3,
        move |x, r| {
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                let (y, t) = yt(i);
                *ri = (-(y - x[1]).abs().powf(x[2]) / x[0]).exp() - t;
            }
        },
        move |x, j| {
            for i in 0..m {
                let (y, _) = yt(i);
                let d = y - x[1];
                let ad = d.abs();
                let a = ad.powf(x[2]);
                let e = (-a / x[0]).exp();
                j[3 * i] = e * a / (x[0] * x[0]);
                if ad == 0.0 {
                    j[3 * i + 1] = 0.0;
                    j[3 * i + 2] = 0.0;
                } else {
                    // d|d|^x3/dx2 = -x3 |d|^(x3-1) sign(d); d|d|^x3/dx3 = |d|^x3 ln|d|.
                    j[3 * i + 1] = e * x[2] * ad.powf(x[2] - 1.0) * d.signum() / x[0];
                    j[3 * i + 2] = -e * a * ad.ln() / x[0];
                }
            }
        },
        vec![5.0, 2.5, 0.15],
        vec![0.0],
        Some(vec![50.0, 25.0, 1.5]),
    )
}

/// (12) Box three-dimensional, n = 3:
/// r_i = exp(-t_i x1) - exp(-t_i x2) - x3 (exp(-t_i) - exp(-10 t_i)), t_i = i/10.
/// f = 0 at (1, 10, 1), (10, 1, -1) and wherever x1 = x2 and x3 = 0.
fn box_3d(m: usize) -> Mgh {
    mgh(
        format!("(12) Box three-dimensional, m={m}"),
        m,
        3,
        move |x, r| {
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                let t = (i + 1) as f64 / 10.0;
                *ri =
                    (-t * x[0]).exp() - (-t * x[1]).exp() - x[2] * ((-t).exp() - (-10.0 * t).exp());
            }
        },
        move |x, j| {
            for i in 0..m {
                let t = (i + 1) as f64 / 10.0;
                j[3 * i] = -t * (-t * x[0]).exp();
                j[3 * i + 1] = t * (-t * x[1]).exp();
                j[3 * i + 2] = -((-t).exp() - (-10.0 * t).exp());
            }
        },
        vec![0.0, 10.0, 20.0],
        vec![0.0],
        Some(vec![1.0, 10.0, 1.0]),
    )
}

/// (13) Powell singular, m = n = 4. f = 0 at the origin.
fn powell_singular() -> Mgh {
    mgh(
        "(13) Powell singular".into(),
        4,
        4,
        powell_block,
        |x, j| {
            zero(j);
            powell_block_jac(x, j, 4, 0);
        },
        vec![3.0, -1.0, 0.0, 1.0],
        vec![0.0],
        Some(vec![0.0; 4]),
    )
}

/// The four Powell singular residuals of x[0..4] into r[0..4].
fn powell_block(x: &[f64], r: &mut [f64]) {
    let s5 = 5.0_f64.sqrt();
    let s10 = 10.0_f64.sqrt();
    r[0] = x[0] + 10.0 * x[1];
    r[1] = s5 * (x[2] - x[3]);
    r[2] = (x[1] - 2.0 * x[2]).powi(2);
    r[3] = s10 * (x[0] - x[3]).powi(2);
}

/// The Jacobian of the Powell block starting at unknown / residual `o`, in a row-major
/// matrix of `n` columns (zeroed by the caller).
fn powell_block_jac(x: &[f64], j: &mut [f64], n: usize, o: usize) {
    let s5 = 5.0_f64.sqrt();
    let s10 = 10.0_f64.sqrt();
    let x = &x[o..o + 4];
    let row = |i: usize, k: usize| (o + i) * n + o + k;
    j[row(0, 0)] = 1.0;
    j[row(0, 1)] = 10.0;
    j[row(1, 2)] = s5;
    j[row(1, 3)] = -s5;
    let a = 2.0 * (x[1] - 2.0 * x[2]);
    j[row(2, 1)] = a;
    j[row(2, 2)] = -2.0 * a;
    let b = 2.0 * s10 * (x[0] - x[3]);
    j[row(3, 0)] = b;
    j[row(3, 3)] = -b;
}

/// (14) Wood, n = 4, m = 6. f = 0 at (1, 1, 1, 1).
fn wood() -> Mgh {
    let s90 = 90.0_f64.sqrt();
    let s10 = 10.0_f64.sqrt();
    mgh(
        "(14) Wood".into(),
        6,
        4,
        move |x, r| {
            r[0] = 10.0 * (x[1] - x[0] * x[0]);
            r[1] = 1.0 - x[0];
            r[2] = s90 * (x[3] - x[2] * x[2]);
            r[3] = 1.0 - x[2];
            r[4] = s10 * (x[1] + x[3] - 2.0);
            r[5] = (x[1] - x[3]) / s10;
        },
        move |x, j| {
            zero(j);
            j[0] = -20.0 * x[0];
            j[1] = 10.0;
            j[4] = -1.0;
            j[2 * 4 + 2] = -2.0 * s90 * x[2];
            j[2 * 4 + 3] = s90;
            j[3 * 4 + 2] = -1.0;
            j[4 * 4 + 1] = s10;
            j[4 * 4 + 3] = s10;
            j[5 * 4 + 1] = 1.0 / s10;
            j[5 * 4 + 3] = -1.0 / s10;
        },
        vec![-3.0, -1.0, -3.0, -1.0],
        vec![0.0],
        Some(vec![1.0; 4]),
    )
}

/// (15) Kowalik and Osborne, n = 4, m = 11:
/// r_i = y_i - x1 (u_i^2 + u_i x2) / (u_i^2 + u_i x3 + x4).
/// f = 3.07505...e-4; f = 1.02734...e-3 at (+inf, -14.07..., -inf, -inf), an infimum: the
/// limit model a u (u + x2) / (u + b) (a = x1/x3, b = x4/x3) fitted; recomputed here.
/// f = 4.2367462647e-4 at (0.22536, -0.41475, -0.024453, -0.17797), a local minimum found
/// by kinecal's Levenberg-Marquardt from 10 x0 (the Hessian there, by finite differences, has
/// eigenvalues 0.032 to 28.7; the model's denominator changes sign between u = 0.25 and 0.167,
/// so this minimum sits across a pole from the global one).
fn kowalik_osborne() -> Mgh {
    const Y: [f64; 11] = [
        0.1957, 0.1947, 0.1735, 0.1600, 0.0844, 0.0627, 0.0456, 0.0342, 0.0323, 0.0235, 0.0246,
    ];
    const U: [f64; 11] = [
        4.0, 2.0, 1.0, 0.5, 0.25, 0.167, 0.125, 0.1, 0.0833, 0.0714, 0.0625,
    ];
    mgh(
        "(15) Kowalik and Osborne".into(),
        11,
        4,
        |x, r| {
            for i in 0..11 {
                let u = U[i];
                r[i] = Y[i] - x[0] * u * (u + x[1]) / (u * (u + x[2]) + x[3]);
            }
        },
        |x, j| {
            for i in 0..11 {
                let u = U[i];
                let num = u * (u + x[1]);
                let den = u * (u + x[2]) + x[3];
                j[4 * i] = -num / den;
                j[4 * i + 1] = -x[0] * u / den;
                j[4 * i + 2] = x[0] * num * u / (den * den);
                j[4 * i + 3] = x[0] * num / (den * den);
            }
        },
        vec![0.25, 0.39, 0.415, 0.39],
        vec![
            3.075_056_038_492_4e-4,
            4.236_746_264_7e-4,
            1.027_343_048_7e-3,
        ],
        None,
    )
}

/// (16) Brown and Dennis, n = 4:
/// r_i = (x1 + t_i x2 - exp(t_i))^2 + (x3 + x4 sin t_i - cos t_i)^2, t_i = i/5.
/// f = 85822.2... for m = 20.
fn brown_dennis(m: usize) -> Mgh {
    assert_eq!(m, 20, "the literature minimum below is for m = 20");
    mgh(
        format!("(16) Brown and Dennis, m={m}"),
        m,
        4,
        move |x, r| {
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                let t = (i + 1) as f64 / 5.0;
                let a = x[0] + t * x[1] - t.exp();
                let b = x[2] + x[3] * t.sin() - t.cos();
                *ri = a * a + b * b;
            }
        },
        move |x, j| {
            for i in 0..m {
                let t = (i + 1) as f64 / 5.0;
                let a = x[0] + t * x[1] - t.exp();
                let b = x[2] + x[3] * t.sin() - t.cos();
                j[4 * i] = 2.0 * a;
                j[4 * i + 1] = 2.0 * a * t;
                j[4 * i + 2] = 2.0 * b;
                j[4 * i + 3] = 2.0 * b * t.sin();
            }
        },
        vec![25.0, 5.0, -5.0, -1.0],
        vec![85_822.201_626_35],
        None,
    )
}

/// (17) Osborne 1, n = 5, m = 33:
/// r_i = y_i - (x1 + x2 exp(-t_i x4) + x3 exp(-t_i x5)), t_i = 10 (i - 1).
/// f = 5.46489...e-5.
fn osborne_1() -> Mgh {
    const Y: [f64; 33] = [
        0.844, 0.908, 0.932, 0.936, 0.925, 0.908, 0.881, 0.850, 0.818, 0.784, 0.751, 0.718, 0.685,
        0.658, 0.628, 0.603, 0.580, 0.558, 0.538, 0.522, 0.506, 0.490, 0.478, 0.467, 0.457, 0.448,
        0.438, 0.431, 0.424, 0.420, 0.414, 0.411, 0.406,
    ];
    mgh(
        "(17) Osborne 1".into(),
        33,
        5,
        |x, r| {
            for i in 0..33 {
                let t = 10.0 * i as f64;
                r[i] = Y[i] - (x[0] + x[1] * (-t * x[3]).exp() + x[2] * (-t * x[4]).exp());
            }
        },
        |x, j| {
            for i in 0..33 {
                let t = 10.0 * i as f64;
                let e4 = (-t * x[3]).exp();
                let e5 = (-t * x[4]).exp();
                j[5 * i] = -1.0;
                j[5 * i + 1] = -e4;
                j[5 * i + 2] = -e5;
                j[5 * i + 3] = x[1] * t * e4;
                j[5 * i + 4] = x[2] * t * e5;
            }
        },
        vec![0.5, 1.5, -1.0, 0.01, 0.02],
        vec![5.464_894_697_483e-5],
        None,
    )
}

/// (18) Biggs EXP6, n = 6, m >= n:
/// r_i = x3 exp(-t_i x1) - x4 exp(-t_i x2) + x6 exp(-t_i x5) - y_i, t_i = i/10,
/// y_i = exp(-t_i) - 5 exp(-10 t_i) + 3 exp(-4 t_i).
/// f = 0 at (1, 10, 1, 5, 4, 3) (for every m); f = 5.65565...e-3 for m = 13, the paper's value,
/// at about (1.7114, 17.6832, 1.16314, 5.18657, 1.7114, 1.16314): there the two exponentials
/// 1 and 3 coincide, and the point is a saddle of f (the Hessian has a negative eigenvalue,
/// about -0.0098), a minimum only within the subspace x1 = x5, x3 = x6.
fn biggs_exp6(m: usize) -> Mgh {
    assert_eq!(m, 13, "the local minimum below is for m = 13");
    mgh(
        format!("(18) Biggs EXP6, m={m}"),
        m,
        6,
        move |x, r| {
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                let t = (i + 1) as f64 / 10.0;
                let y = (-t).exp() - 5.0 * (-10.0 * t).exp() + 3.0 * (-4.0 * t).exp();
                *ri = x[2] * (-t * x[0]).exp() - x[3] * (-t * x[1]).exp()
                    + x[5] * (-t * x[4]).exp()
                    - y;
            }
        },
        move |x, j| {
            for i in 0..m {
                let t = (i + 1) as f64 / 10.0;
                let e1 = (-t * x[0]).exp();
                let e2 = (-t * x[1]).exp();
                let e5 = (-t * x[4]).exp();
                let row = &mut j[6 * i..6 * i + 6];
                row[0] = -t * x[2] * e1;
                row[1] = t * x[3] * e2;
                row[2] = e1;
                row[3] = -e2;
                row[4] = -t * x[5] * e5;
                row[5] = e5;
            }
        },
        vec![1.0, 2.0, 1.0, 1.0, 1.0, 1.0],
        vec![0.0, 5.655_649_903e-3],
        Some(vec![1.0, 10.0, 1.0, 5.0, 4.0, 3.0]),
    )
}

/// (19) Osborne 2, n = 11, m = 65:
/// r_i = y_i - (x1 exp(-t_i x5) + x2 exp(-(t_i - x9)^2 x6) + x3 exp(-(t_i - x10)^2 x7)
///              + x4 exp(-(t_i - x11)^2 x8)), t_i = (i - 1)/10.
/// f = 4.01377...e-2.
fn osborne_2() -> Mgh {
    const Y: [f64; 65] = [
        1.366, 1.191, 1.112, 1.013, 0.991, 0.885, 0.831, 0.847, 0.786, 0.725, 0.746, 0.679, 0.608,
        0.655, 0.616, 0.606, 0.602, 0.626, 0.651, 0.724, 0.649, 0.649, 0.694, 0.644, 0.624, 0.661,
        0.612, 0.558, 0.533, 0.495, 0.500, 0.423, 0.395, 0.375, 0.372, 0.391, 0.396, 0.405, 0.428,
        0.429, 0.523, 0.562, 0.607, 0.653, 0.672, 0.708, 0.633, 0.668, 0.645, 0.632, 0.591, 0.559,
        0.597, 0.625, 0.739, 0.710, 0.729, 0.720, 0.636, 0.581, 0.428, 0.292, 0.162, 0.098, 0.054,
    ];
    mgh(
        "(19) Osborne 2".into(),
        65,
        11,
        |x, r| {
            for i in 0..65 {
                let t = i as f64 / 10.0;
                let g = |a: f64, c: f64| (-(t - c) * (t - c) * a).exp();
                r[i] = Y[i]
                    - (x[0] * (-t * x[4]).exp()
                        + x[1] * g(x[5], x[8])
                        + x[2] * g(x[6], x[9])
                        + x[3] * g(x[7], x[10]));
            }
        },
        |x, j| {
            zero(j);
            for i in 0..65 {
                let t = i as f64 / 10.0;
                let row = &mut j[11 * i..11 * i + 11];
                let e = (-t * x[4]).exp();
                row[0] = -e;
                row[4] = x[0] * t * e;
                // Gaussian bumps k = 1, 2, 3: amplitude x[k], width x[k + 4], centre x[k + 7].
                for k in 1..4 {
                    let d = t - x[k + 7];
                    let g = (-d * d * x[k + 4]).exp();
                    row[k] = -g;
                    row[k + 4] = x[k] * d * d * g;
                    row[k + 7] = -2.0 * x[k] * x[k + 4] * d * g;
                }
            }
        },
        vec![1.3, 0.65, 0.65, 0.7, 0.6, 3.0, 5.0, 7.0, 2.0, 4.5, 5.5],
        vec![4.013_773_629_354_77e-2],
        None,
    )
}

/// (20) Watson, 2 <= n <= 31, m = 31: for t_i = i/29, i = 1..29,
/// r_i = sum_{j=2}^n (j-1) x_j t_i^(j-2) - (sum_{j=1}^n x_j t_i^(j-1))^2 - 1,
/// r_30 = x1, r_31 = x2 - x1^2 - 1.
/// f = 2.28767...e-3 (n = 6), 1.39976...e-6 (n = 9), 4.72238...e-10 (n = 12).
fn watson(n: usize) -> Mgh {
    let fmin = match n {
        6 => 2.287_670_053_552_4e-3,
        9 => 1.399_760_138_09e-6,
        12 => 4.722_381_1e-10,
        _ => panic!("no literature minimum for Watson with n = {n}"),
    };
    mgh(
        format!("(20) Watson, n={n}"),
        31,
        n,
        move |x, r| {
            for (i, ri) in r.iter_mut().enumerate().take(29) {
                let t = (i + 1) as f64 / 29.0;
                let (mut s1, mut s2, mut p) = (0.0, x[0], 1.0);
                for (k, xk) in x.iter().enumerate().take(n).skip(1) {
                    // p = t^(k-1) here; x[k] is x_{k+1}.
                    s1 += k as f64 * p * xk;
                    p *= t;
                    s2 += p * xk;
                }
                *ri = s1 - s2 * s2 - 1.0;
            }
            r[29] = x[0];
            r[30] = x[1] - x[0] * x[0] - 1.0;
        },
        move |x, j| {
            zero(j);
            for i in 0..29 {
                let t = (i + 1) as f64 / 29.0;
                let (mut s2, mut p) = (0.0, 1.0);
                for xk in x.iter().take(n) {
                    s2 += p * xk;
                    p *= t;
                }
                let row = &mut j[n * i..n * i + n];
                // d r_i / d x_{k+1} = k t^(k-1) - 2 s2 t^k.
                let mut p = 1.0; // t^k
                let mut pm1 = 0.0; // t^(k-1), 0 for k = 0
                for (k, jk) in row.iter_mut().enumerate() {
                    *jk = k as f64 * pm1 - 2.0 * s2 * p;
                    pm1 = p;
                    p *= t;
                }
            }
            j[29 * n] = 1.0;
            j[30 * n] = -2.0 * x[0];
            j[30 * n + 1] = 1.0;
        },
        vec![0.0; n],
        vec![fmin],
        None,
    )
}

/// (21) Extended Rosenbrock, n even, m = n. f = 0 at (1, ..., 1).
fn extended_rosenbrock(n: usize) -> Mgh {
    assert_eq!(n % 2, 0, "n is even");
    mgh(
        format!("(21) Extended Rosenbrock, n={n}"),
        n,
        n,
        move |x, r| {
            for i in (0..n).step_by(2) {
                r[i] = 10.0 * (x[i + 1] - x[i] * x[i]);
                r[i + 1] = 1.0 - x[i];
            }
        },
        move |x, j| {
            zero(j);
            for i in (0..n).step_by(2) {
                j[i * n + i] = -20.0 * x[i];
                j[i * n + i + 1] = 10.0;
                j[(i + 1) * n + i] = -1.0;
            }
        },
        (0..n)
            .map(|i| if i % 2 == 0 { -1.2 } else { 1.0 })
            .collect(),
        vec![0.0],
        Some(vec![1.0; n]),
    )
}

/// (22) Extended Powell singular, n a multiple of 4, m = n. f = 0 at the origin.
fn extended_powell(n: usize) -> Mgh {
    assert_eq!(n % 4, 0, "n is a multiple of 4");
    mgh(
        format!("(22) Extended Powell singular, n={n}"),
        n,
        n,
        move |x, r| {
            for o in (0..n).step_by(4) {
                powell_block(&x[o..o + 4], &mut r[o..o + 4]);
            }
        },
        move |x, j| {
            zero(j);
            for o in (0..n).step_by(4) {
                powell_block_jac(x, j, n, o);
            }
        },
        (0..n).map(|i| [3.0, -1.0, 0.0, 1.0][i % 4]).collect(),
        vec![0.0],
        Some(vec![0.0; n]),
    )
}

/// (23) Penalty I, m = n + 1: r_i = sqrt(a) (x_i - 1), i = 1..n, a = 1e-5;
/// r_{n+1} = sum x_j^2 - 1/4. f = 2.24997...e-5 (n = 4), 7.08765...e-5 (n = 10).
fn penalty_1(n: usize) -> Mgh {
    assert_eq!(n, 10, "the literature minimum below is for n = 10");
    let fmin = 7.087_651_467_09e-5;
    let sa = 1e-5_f64.sqrt();
    mgh(
        format!("(23) Penalty I, n={n}"),
        n + 1,
        n,
        move |x, r| {
            for (ri, xi) in r.iter_mut().zip(x).take(n) {
                *ri = sa * (xi - 1.0);
            }
            r[n] = x.iter().map(|v| v * v).sum::<f64>() - 0.25;
        },
        move |x, j| {
            zero(j);
            for i in 0..n {
                j[i * n + i] = sa;
                j[n * n + i] = 2.0 * x[i];
            }
        },
        (1..=n).map(|k| k as f64).collect(),
        vec![fmin],
        None,
    )
}

/// (24) Penalty II, m = 2n, a = 1e-5: r_1 = x1 - 0.2;
/// r_i = sqrt(a) (exp(x_i/10) + exp(x_{i-1}/10) - y_i), y_i = exp(i/10) + exp((i-1)/10),
/// 2 <= i <= n; r_i = sqrt(a) (exp(x_{i-n+1}/10) - exp(-1/10)), n < i < 2n;
/// r_2n = sum_j (n - j + 1) x_j^2 - 1. f = 9.37629...e-6 (n = 4), 2.93660...e-4 (n = 10).
fn penalty_2(n: usize) -> Mgh {
    assert_eq!(n, 10, "the literature minimum below is for n = 10");
    let fmin = 2.936_605_374_57e-4;
    let sa = 1e-5_f64.sqrt();
    mgh(
        format!("(24) Penalty II, n={n}"),
        2 * n,
        n,
        move |x, r| {
            r[0] = x[0] - 0.2;
            for i in 1..n {
                let y = ((i + 1) as f64 / 10.0).exp() + (i as f64 / 10.0).exp();
                r[i] = sa * ((x[i] / 10.0).exp() + (x[i - 1] / 10.0).exp() - y);
                r[n + i - 1] = sa * ((x[i] / 10.0).exp() - (-0.1_f64).exp());
            }
            r[2 * n - 1] = x
                .iter()
                .enumerate()
                .map(|(k, v)| (n - k) as f64 * v * v)
                .sum::<f64>()
                - 1.0;
        },
        move |x, j| {
            zero(j);
            j[0] = 1.0;
            for i in 1..n {
                j[i * n + i] = sa * (x[i] / 10.0).exp() / 10.0;
                j[i * n + i - 1] = sa * (x[i - 1] / 10.0).exp() / 10.0;
                j[(n + i - 1) * n + i] = sa * (x[i] / 10.0).exp() / 10.0;
            }
            for k in 0..n {
                j[(2 * n - 1) * n + k] = 2.0 * (n - k) as f64 * x[k];
            }
        },
        vec![0.5; n],
        vec![fmin],
        None,
    )
}

/// (25) Variably dimensioned, m = n + 2: r_i = x_i - 1, i = 1..n;
/// r_{n+1} = sum_j j (x_j - 1); r_{n+2} = (sum_j j (x_j - 1))^2. f = 0 at (1, ..., 1).
fn variably_dimensioned(n: usize) -> Mgh {
    mgh(
        format!("(25) Variably dimensioned, n={n}"),
        n + 2,
        n,
        move |x, r| {
            let mut s = 0.0;
            for i in 0..n {
                r[i] = x[i] - 1.0;
                s += (i + 1) as f64 * (x[i] - 1.0);
            }
            r[n] = s;
            r[n + 1] = s * s;
        },
        move |x, j| {
            zero(j);
            let s: f64 = (0..n).map(|i| (i + 1) as f64 * (x[i] - 1.0)).sum();
            for i in 0..n {
                j[i * n + i] = 1.0;
                j[n * n + i] = (i + 1) as f64;
                j[(n + 1) * n + i] = 2.0 * s * (i + 1) as f64;
            }
        },
        (1..=n).map(|k| 1.0 - k as f64 / n as f64).collect(),
        vec![0.0],
        Some(vec![1.0; n]),
    )
}

/// (26) Trigonometric, m = n: r_i = n - sum_j cos x_j + i (1 - cos x_i) - sin x_i.
/// f = 0 (the paper). For n = 10 there are local minima as well: 2.79506...e-5 is the one
/// reported in the literature for n = 10; 4.47357e-7, 4.21863e-5 and 8.78823e-4 were found
/// here (Levenberg-Marquardt from random points near x0; positive definite Hessians).
fn trigonometric(n: usize) -> Mgh {
    assert_eq!(n, 10, "the local minima below are for n = 10");
    let minima = vec![
        0.0,
        4.473_565_812_8e-7,
        2.795_056_121_9e-5,
        4.218_633_887_9e-5,
        8.788_225_218_2e-4,
    ];
    mgh(
        format!("(26) Trigonometric, n={n}"),
        n,
        n,
        move |x, r| {
            let c: f64 = x.iter().map(|v| v.cos()).sum();
            for i in 0..n {
                r[i] = n as f64 - c + (i + 1) as f64 * (1.0 - x[i].cos()) - x[i].sin();
            }
        },
        move |x, j| {
            for i in 0..n {
                for k in 0..n {
                    j[i * n + k] = x[k].sin();
                }
                j[i * n + i] += (i + 1) as f64 * x[i].sin() - x[i].cos();
            }
        },
        vec![1.0 / n as f64; n],
        minima,
        None,
    )
}

/// (27) Brown almost-linear, m = n: r_i = x_i + sum_j x_j - (n + 1), 1 <= i < n;
/// r_n = prod_j x_j - 1. f = 0 at (a, ..., a, a^(1-n)) with n a^n - (n+1) a^(n-1) + 1 = 0,
/// in particular at (1, ..., 1); f = 1 at (0, ..., 0, n + 1).
fn brown_almost_linear(n: usize) -> Mgh {
    mgh(
        format!("(27) Brown almost-linear, n={n}"),
        n,
        n,
        move |x, r| {
            let s: f64 = x.iter().sum();
            for i in 0..n - 1 {
                r[i] = x[i] + s - (n + 1) as f64;
            }
            r[n - 1] = x.iter().product::<f64>() - 1.0;
        },
        move |x, j| {
            for i in 0..n - 1 {
                for k in 0..n {
                    j[i * n + k] = if i == k { 2.0 } else { 1.0 };
                }
            }
            // prod_{l != k} x_l by prefix and suffix products (no division by x_k).
            let mut pre = 1.0;
            for k in 0..n {
                j[(n - 1) * n + k] = pre;
                pre *= x[k];
            }
            let mut suf = 1.0;
            for k in (0..n).rev() {
                j[(n - 1) * n + k] *= suf;
                suf *= x[k];
            }
        },
        vec![0.5; n],
        vec![0.0, 1.0],
        Some(vec![1.0; n]),
    )
}

/// t_j (t_j - 1), t_j = j h, h = 1/(n+1): the start of (28) and (29).
fn bv_start(n: usize) -> Vec<f64> {
    let h = 1.0 / (n + 1) as f64;
    (1..=n)
        .map(|k| k as f64 * h * (k as f64 * h - 1.0))
        .collect()
}

/// (28) Discrete boundary value, m = n, h = 1/(n+1), t_i = i h, x_0 = x_{n+1} = 0:
/// r_i = 2 x_i - x_{i-1} - x_{i+1} + h^2 (x_i + t_i + 1)^3 / 2. f = 0.
fn discrete_boundary_value(n: usize) -> Mgh {
    let h = 1.0 / (n + 1) as f64;
    mgh(
        format!("(28) Discrete boundary value, n={n}"),
        n,
        n,
        move |x, r| {
            for i in 0..n {
                let t = (i + 1) as f64 * h;
                let xm = if i > 0 { x[i - 1] } else { 0.0 };
                let xp = if i + 1 < n { x[i + 1] } else { 0.0 };
                r[i] = 2.0 * x[i] - xm - xp + h * h * (x[i] + t + 1.0).powi(3) / 2.0;
            }
        },
        move |x, j| {
            zero(j);
            for i in 0..n {
                let t = (i + 1) as f64 * h;
                j[i * n + i] = 2.0 + 1.5 * h * h * (x[i] + t + 1.0).powi(2);
                if i > 0 {
                    j[i * n + i - 1] = -1.0;
                }
                if i + 1 < n {
                    j[i * n + i + 1] = -1.0;
                }
            }
        },
        bv_start(n),
        vec![0.0],
        None,
    )
}

/// (29) Discrete integral equation, m = n, h = 1/(n+1), t_i = i h:
/// r_i = x_i + h [(1 - t_i) sum_{j<=i} t_j (x_j + t_j + 1)^3
///                + t_i sum_{j>i} (1 - t_j) (x_j + t_j + 1)^3] / 2. f = 0.
fn discrete_integral_equation(n: usize) -> Mgh {
    let h = 1.0 / (n + 1) as f64;
    mgh(
        format!("(29) Discrete integral equation, n={n}"),
        n,
        n,
        move |x, r| {
            for i in 0..n {
                let ti = (i + 1) as f64 * h;
                let (mut s1, mut s2) = (0.0, 0.0);
                for (k, xk) in x.iter().enumerate().take(n) {
                    let tk = (k + 1) as f64 * h;
                    let c = (xk + tk + 1.0).powi(3);
                    if k <= i {
                        s1 += tk * c;
                    } else {
                        s2 += (1.0 - tk) * c;
                    }
                }
                r[i] = x[i] + h * ((1.0 - ti) * s1 + ti * s2) / 2.0;
            }
        },
        move |x, j| {
            for i in 0..n {
                let ti = (i + 1) as f64 * h;
                for k in 0..n {
                    let tk = (k + 1) as f64 * h;
                    let dc = 3.0 * (x[k] + tk + 1.0).powi(2);
                    let w = if k <= i {
                        (1.0 - ti) * tk
                    } else {
                        ti * (1.0 - tk)
                    };
                    j[i * n + k] = h * w * dc / 2.0 + if i == k { 1.0 } else { 0.0 };
                }
            }
        },
        bv_start(n),
        vec![0.0],
        None,
    )
}

/// (30) Broyden tridiagonal, m = n, x_0 = x_{n+1} = 0:
/// r_i = (3 - 2 x_i) x_i - x_{i-1} - 2 x_{i+1} + 1. f = 0.
fn broyden_tridiagonal(n: usize) -> Mgh {
    mgh(
        format!("(30) Broyden tridiagonal, n={n}"),
        n,
        n,
        move |x, r| {
            for i in 0..n {
                let xm = if i > 0 { x[i - 1] } else { 0.0 };
                let xp = if i + 1 < n { x[i + 1] } else { 0.0 };
                r[i] = (3.0 - 2.0 * x[i]) * x[i] - xm - 2.0 * xp + 1.0;
            }
        },
        move |x, j| {
            zero(j);
            for i in 0..n {
                j[i * n + i] = 3.0 - 4.0 * x[i];
                if i > 0 {
                    j[i * n + i - 1] = -1.0;
                }
                if i + 1 < n {
                    j[i * n + i + 1] = -2.0;
                }
            }
        },
        vec![-1.0; n],
        vec![0.0],
        None,
    )
}

/// (31) Broyden banded, m = n, m_l = 5, m_u = 1:
/// r_i = x_i (2 + 5 x_i^2) + 1 - sum_{j in J_i} x_j (1 + x_j),
/// J_i = { j != i : max(1, i - m_l) <= j <= min(n, i + m_u) }. f = 0.
fn broyden_banded(n: usize) -> Mgh {
    let band = move |i: usize| (i.saturating_sub(5)..=(i + 1).min(n - 1)).filter(move |&k| k != i);
    mgh(
        format!("(31) Broyden banded, n={n}"),
        n,
        n,
        move |x, r| {
            for i in 0..n {
                let s: f64 = band(i).map(|k| x[k] * (1.0 + x[k])).sum();
                r[i] = x[i] * (2.0 + 5.0 * x[i] * x[i]) + 1.0 - s;
            }
        },
        move |x, j| {
            zero(j);
            for i in 0..n {
                j[i * n + i] = 2.0 + 15.0 * x[i] * x[i];
                for k in band(i) {
                    j[i * n + k] = -(1.0 + 2.0 * x[k]);
                }
            }
        },
        vec![-1.0; n],
        vec![0.0],
        None,
    )
}

/// (32) Linear function - full rank, m >= n: r_i = x_i - (2/m) sum_j x_j - 1, i <= n;
/// r_i = -(2/m) sum_j x_j - 1, i > n. f = m - n at (-1, ..., -1).
fn linear_full_rank(n: usize, m: usize) -> Mgh {
    mgh(
        format!("(32) Linear function - full rank, n={n}, m={m}"),
        m,
        n,
        move |x, r| {
            let s: f64 = x.iter().sum();
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                *ri = -2.0 * s / m as f64 - 1.0 + if i < n { x[i] } else { 0.0 };
            }
        },
        move |_x, j| {
            for i in 0..m {
                for k in 0..n {
                    j[i * n + k] = -2.0 / m as f64 + if i == k { 1.0 } else { 0.0 };
                }
            }
        },
        vec![1.0; n],
        vec![(m - n) as f64],
        Some(vec![-1.0; n]),
    )
}

/// (33) Linear function - rank 1, m >= n: r_i = i (sum_j j x_j) - 1.
/// f = m (m - 1) / (2 (2m + 1)) wherever sum_j j x_j = 3 / (2m + 1).
fn linear_rank_1(n: usize, m: usize) -> Mgh {
    let mf = m as f64;
    let mut xmin = vec![0.0; n];
    xmin[0] = 3.0 / (2.0 * mf + 1.0);
    mgh(
        format!("(33) Linear function - rank 1, n={n}, m={m}"),
        m,
        n,
        move |x, r| {
            let s: f64 = x.iter().enumerate().map(|(k, v)| (k + 1) as f64 * v).sum();
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                *ri = (i + 1) as f64 * s - 1.0;
            }
        },
        move |_x, j| {
            for i in 0..m {
                for k in 0..n {
                    j[i * n + k] = ((i + 1) * (k + 1)) as f64;
                }
            }
        },
        vec![1.0; n],
        vec![mf * (mf - 1.0) / (2.0 * (2.0 * mf + 1.0))],
        Some(xmin),
    )
}

/// (34) Linear function - rank 1 with zero columns and rows, m >= n >= 3:
/// r_1 = -1; r_i = (i - 1) (sum_{j=2}^{n-1} j x_j) - 1, 2 <= i <= m - 1; r_m = -1.
/// f = (m^2 + 3m - 6) / (2 (2m - 3)) wherever sum_{j=2}^{n-1} j x_j = 3 / (2m - 3).
fn linear_rank_1_zero(n: usize, m: usize) -> Mgh {
    assert!(n >= 3);
    let mf = m as f64;
    let mut xmin = vec![0.0; n];
    xmin[1] = 3.0 / (2.0 * (2.0 * mf - 3.0));
    mgh(
        format!("(34) Linear function - rank 1 with zero columns and rows, n={n}, m={m}"),
        m,
        n,
        move |x, r| {
            let s: f64 = (1..n - 1).map(|k| (k + 1) as f64 * x[k]).sum();
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                *ri = i as f64 * s - 1.0;
            }
            r[m - 1] = -1.0;
        },
        move |_x, j| {
            zero(j);
            for i in 1..m - 1 {
                for k in 1..n - 1 {
                    j[i * n + k] = (i * (k + 1)) as f64;
                }
            }
        },
        vec![1.0; n],
        vec![(mf * mf + 3.0 * mf - 6.0) / (2.0 * (2.0 * mf - 3.0))],
        Some(xmin),
    )
}

/// (35) Chebyquad, m >= n: r_i = (1/n) sum_j T_i(2 x_j - 1) - I_i, with T_i the Chebyshev
/// polynomial of degree i and I_i = int_0^1 T_i(2s - 1) ds = -1/(i^2 - 1) for even i, 0 for
/// odd i. x0_j = j/(n+1). The paper: f = 0 for m = n = 1..7 and 9, 3.51687...e-3 for
/// m = n = 8, 6.50395...e-3 for m = n = 10. For m = n = 10 a lower local minimum,
/// 4.77271...e-3, is in Moré and Wild's (2009) benchmark data, and 9.50063e-3 is another local
/// minimum found here. n = 1, m = 8 is not in the paper: MINPACK's lmder reaches
/// 3.55039... (= 1.8842482^2) from 10 x0 and 100 x0 and stops at x0 = 1/2 with 3.55789...
/// (= 1.8862380^2): the gradient vanishes there by symmetry, but it is a local MAXIMUM, listed
/// so that a solver stopping at x0 is recognised; the local minima of this one-dimensional f
/// (found here) are 3.06653 (x = 0.409, 0.591), 3.23909 (x = 0.241, 0.759),
/// 3.49148 (x = 0.102, 0.898) and 3.55039 (x = 0.018, 0.982).
fn chebyquad(n: usize, m: usize) -> Mgh {
    let minima = match (n, m) {
        (1, 8) => vec![
            3.066_527_232_4,
            3.239_086_001_2,
            3.491_482_170_1,
            3.550_391_297_7,
            3.557_893_676_0,
        ],
        (8, 8) => vec![3.516_873_725_677e-3],
        (9, 9) => vec![0.0],
        (10, 10) => vec![
            4.772_713_696_375_36e-3,
            6.503_954_800_9e-3,
            9.500_628_850_2e-3,
        ],
        _ => panic!("no literature minimum for Chebyquad with n = {n}, m = {m}"),
    };
    // T_i(z) and T_i'(z) for i = 1..=m into t[i-1], d[i-1].
    let cheb = move |z: f64, t: &mut [f64], d: &mut [f64]| {
        let (mut t0, mut t1, mut d0, mut d1) = (1.0, z, 0.0, 1.0);
        for i in 0..m {
            t[i] = t1;
            d[i] = d1;
            let t2 = 2.0 * z * t1 - t0;
            let d2 = 2.0 * t1 + 2.0 * z * d1 - d0;
            t0 = t1;
            t1 = t2;
            d0 = d1;
            d1 = d2;
        }
    };
    let name = if n == m {
        format!("(35) Chebyquad, n={n}")
    } else {
        format!("(35) Chebyquad, n={n}, m={m}")
    };
    mgh(
        name,
        m,
        n,
        move |x, r| {
            let (mut t, mut d) = (vec![0.0; m], vec![0.0; m]);
            r.iter_mut().for_each(|v| *v = 0.0);
            for xk in x.iter().take(n) {
                cheb(2.0 * xk - 1.0, &mut t, &mut d);
                for i in 0..m {
                    r[i] += t[i] / n as f64;
                }
            }
            for (i, ri) in r.iter_mut().enumerate().take(m) {
                let deg = (i + 1) as f64;
                if (i + 1) % 2 == 0 {
                    *ri += 1.0 / (deg * deg - 1.0);
                }
            }
        },
        move |x, j| {
            let (mut t, mut d) = (vec![0.0; m], vec![0.0; m]);
            for (k, xk) in x.iter().enumerate().take(n) {
                cheb(2.0 * xk - 1.0, &mut t, &mut d);
                for i in 0..m {
                    j[i * n + k] = 2.0 * d[i] / n as f64;
                }
            }
        },
        (1..=n).map(|k| k as f64 / (n + 1) as f64).collect(),
        minima,
        None,
    )
}

// ----------------------------------------------------------------------------------------

#[cfg(test)]
mod check {
    use super::*;

    /// Deterministic numbers in [-1, 1].
    fn pattern(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
            })
            .collect()
    }

    /// The start, and two points near it (relative perturbations of 10 % and 3 %).
    fn test_points(p: &Mgh) -> Vec<Vec<f64>> {
        let mut pts = vec![p.start.clone()];
        for (seed, amp) in [(1u64, 0.1), (2, 0.03)] {
            let d = pattern(seed + 7 * p.n as u64 + p.m as u64, p.n);
            pts.push(
                p.start
                    .iter()
                    .zip(&d)
                    .map(|(x, d)| x + amp * d * (1.0 + x.abs()))
                    .collect(),
            );
        }
        pts
    }

    #[test]
    fn lengths_are_consistent() {
        let ps = problems();
        assert!(ps.len() >= 34);
        let mut names: Vec<&str> = ps.iter().map(|p| p.name.as_str()).collect();
        names.sort();
        let count = names.len();
        names.dedup();
        assert_eq!(names.len(), count, "names are unique");
        for number in 1..=34 {
            let tag = format!("({number}) ");
            assert!(
                ps.iter().any(|p| p.name.starts_with(&tag)),
                "problem {number} is present"
            );
        }
        for p in &ps {
            assert!(p.n >= 1 && p.m >= p.n, "{}: m >= n >= 1", p.name);
            assert_eq!(p.start.len(), p.n, "{}: start", p.name);
            assert!(!p.minima.is_empty(), "{}: minima", p.name);
            assert!(
                p.minima.iter().all(|f| f.is_finite() && *f >= 0.0),
                "{}",
                p.name
            );
            assert!(
                p.minima.windows(2).all(|w| w[0] < w[1]),
                "{}: ascending",
                p.name
            );
            if let Some(xm) = &p.minimiser {
                assert_eq!(xm.len(), p.n, "{}: minimiser", p.name);
            }
            let mut r = vec![f64::NAN; p.m];
            let mut j = vec![f64::NAN; p.m * p.n];
            (p.residuals)(&p.start, &mut r);
            (p.jacobian)(&p.start, &mut j);
            assert!(
                r.iter().all(|v| v.is_finite()),
                "{}: r(x0) is finite and complete",
                p.name
            );
            assert!(
                j.iter().all(|v| v.is_finite()),
                "{}: J(x0) is finite and complete",
                p.name
            );
            let f0 = sum_sq(p, &p.start);
            assert!(
                f0 > p.minima[0],
                "{}: f(x0) = {f0} above the minimum",
                p.name
            );
        }
    }

    /// MINPACK's `lmder` test driver (`ssq.data`, reference output of the Fortran driver as
    /// distributed with MINPACK / cminpack): the problem, the initial and the final l2 norm of
    /// the residuals, for each of its 53 runs.
    const LMDER_RUNS: &[(&str, f64, f64)] = &[
        (
            "(32) Linear function - full rank, n=5, m=10",
            5.0000000e+00,
            2.2360680e+00,
        ),
        (
            "(32) Linear function - full rank, n=5, m=50",
            8.0622577e+00,
            6.7082039e+00,
        ),
        (
            "(33) Linear function - rank 1, n=5, m=10",
            2.9152187e+02,
            1.4638501e+00,
        ),
        (
            "(33) Linear function - rank 1, n=5, m=50",
            3.1016004e+03,
            3.4826302e+00,
        ),
        (
            "(34) Linear function - rank 1 with zero columns and rows, n=5, m=10",
            1.2603968e+02,
            1.9097274e+00,
        ),
        (
            "(34) Linear function - rank 1 with zero columns and rows, n=5, m=50",
            1.7489500e+03,
            3.6917294e+00,
        ),
        ("(1) Rosenbrock", 4.9193496e+00, 0.0000000e+00),
        ("(1) Rosenbrock, 10 x0", 1.3400631e+03, 0.0000000e+00),
        ("(1) Rosenbrock, 100 x0", 1.4300005e+05, 0.0000000e+00),
        ("(7) Helical valley", 5.0000000e+01, 9.9365231e-17),
        ("(7) Helical valley, 10 x0", 1.0295630e+02, 1.0446727e-19),
        ("(7) Helical valley, 100 x0", 9.9126182e+02, 3.4526556e-29),
        ("(13) Powell singular", 1.4662878e+01, 3.3916607e-167),
        ("(13) Powell singular, 10 x0", 1.2709839e+03, 3.6588477e-37),
        ("(13) Powell singular, 100 x0", 1.2688790e+05, 9.3192613e-35),
        ("(2) Freudenstein and Roth", 2.0012496e+01, 6.9988752e+00),
        (
            "(2) Freudenstein and Roth, 10 x0",
            1.2432834e+04,
            6.9988752e+00,
        ),
        (
            "(2) Freudenstein and Roth, 100 x0",
            1.1426455e+07,
            6.9988752e+00,
        ),
        ("(8) Bard", 6.4561363e+00, 9.0635960e-02),
        ("(8) Bard, 10 x0", 3.6141853e+01, 4.1747687e+00),
        ("(8) Bard, 100 x0", 3.8411468e+02, 4.1747687e+00),
        ("(15) Kowalik and Osborne", 7.2891510e-02, 1.7535838e-02),
        (
            "(15) Kowalik and Osborne, 10 x0",
            2.9793701e+00,
            3.2052193e-02,
        ),
        (
            "(15) Kowalik and Osborne, 100 x0",
            2.9959062e+01,
            1.7535838e-02,
        ),
        ("(10) Meyer", 4.1153467e+04, 9.3779451e+00),
        ("(10) Meyer, 10 x0", 4.1682169e+06, 7.9509584e+02),
        ("(20) Watson, n=6", 5.4772256e+00, 4.7829594e-02),
        ("(20) Watson, n=6, 10 x0", 6.4331258e+03, 4.7829594e-02),
        ("(20) Watson, n=6, 100 x0", 6.7425604e+05, 4.7829594e-02),
        ("(20) Watson, n=9", 5.4772256e+00, 1.1831146e-03),
        ("(20) Watson, n=9, 10 x0", 1.2088127e+04, 1.1831146e-03),
        ("(20) Watson, n=9, 100 x0", 1.2691093e+06, 1.1831146e-03),
        ("(20) Watson, n=12", 5.4772256e+00, 2.1731040e-05),
        ("(20) Watson, n=12, 10 x0", 1.9220759e+04, 2.1731040e-05),
        ("(20) Watson, n=12, 100 x0", 2.0189180e+06, 2.1731040e-05),
        (
            "(12) Box three-dimensional, m=10",
            3.2111584e+01,
            2.8529818e-16,
        ),
        (
            "(6) Jennrich and Sampson, m=10",
            6.4585650e+01,
            1.1151779e+01,
        ),
        ("(16) Brown and Dennis, m=20", 2.8154384e+03, 2.9295429e+02),
        (
            "(16) Brown and Dennis, m=20, 10 x0",
            5.5507335e+05,
            2.9295427e+02,
        ),
        (
            "(16) Brown and Dennis, m=20, 100 x0",
            6.1211252e+07,
            2.9295431e+02,
        ),
        ("(35) Chebyquad, n=1, m=8", 1.8862380e+00, 1.8862380e+00),
        (
            "(35) Chebyquad, n=1, m=8, 10 x0",
            5.3833444e+09,
            1.8842482e+00,
        ),
        (
            "(35) Chebyquad, n=1, m=8, 100 x0",
            1.1808873e+18,
            1.8842482e+00,
        ),
        ("(35) Chebyquad, n=8", 1.9651386e-01, 5.9303236e-02),
        ("(35) Chebyquad, n=9", 1.6994993e-01, 1.2137434e-16),
        ("(35) Chebyquad, n=10", 1.8374783e-01, 8.0647100e-02),
        (
            "(27) Brown almost-linear, n=10",
            1.6530216e+01,
            8.6625859e-15,
        ),
        (
            "(27) Brown almost-linear, n=10, 10 x0",
            9.7656240e+06,
            5.0009355e-15,
        ),
        (
            "(27) Brown almost-linear, n=10, 100 x0",
            9.7656250e+16,
            5.3290705e-15,
        ),
        (
            "(27) Brown almost-linear, n=30",
            8.3476044e+01,
            1.4827859e-13,
        ),
        (
            "(27) Brown almost-linear, n=40",
            1.2802636e+02,
            2.0245354e-13,
        ),
        ("(17) Osborne 1", 9.3756402e-01, 7.3924926e-03),
        ("(19) Osborne 2", 1.4468654e+00, 2.0034404e-01),
    ];

    #[test]
    fn starts_match_minpack_lmder_initial_norms() {
        let ps = problems();
        for (name, initial, _) in LMDER_RUNS {
            let p = ps
                .iter()
                .find(|p| p.name == *name)
                .unwrap_or_else(|| panic!("{name}"));
            let norm = sum_sq(p, &p.start).sqrt();
            assert!(
                (norm - initial).abs() <= 1e-7 * initial,
                "{name}: ||r(x0)|| = {norm}, MINPACK {initial}"
            );
        }
    }

    #[test]
    fn minpack_lmder_final_norms_are_listed_minima() {
        let ps = problems();
        for (name, _, fin) in LMDER_RUNS {
            // The one run where lmder fails (info = 5, too many evaluations).
            if *name == "(10) Meyer, 10 x0" {
                continue;
            }
            let p = ps.iter().find(|p| p.name == *name).unwrap();
            let f = fin * fin;
            assert!(
                p.minima.iter().any(|m| (f - m).abs() <= 1e-6 * m + 1e-20),
                "{name}: lmder's final f = {f} is not among {:?}",
                p.minima
            );
        }
    }

    #[test]
    fn other_literature_values() {
        // Starting values of f in Moré and Wild's (2009) benchmark data.
        let want: &[(&str, f64)] = &[
            ("(1) Rosenbrock, 10 x0", 1.795769e6),
            ("(7) Helical valley, 10 x0", 10600.0),
            ("(13) Powell singular, 10 x0", 1.615400e6),
            ("(2) Freudenstein and Roth, 10 x0", 1.545754e8),
            ("(8) Bard, 10 x0", 1306.234),
            ("(15) Kowalik and Osborne", 5.313172e-3),
            ("(10) Meyer", 1.693608e9),
            ("(12) Box three-dimensional, m=10", 1031.154),
            ("(6) Jennrich and Sampson, m=10", 4171.306),
            ("(16) Brown and Dennis, m=20, 10 x0", 3.081064e11),
            ("(27) Brown almost-linear, n=10", 273.2480),
            ("(19) Osborne 2", 2.093420),
            ("(35) Chebyquad, n=8", 3.861770e-2),
            ("(35) Chebyquad, n=9", 2.888298e-2),
            ("(35) Chebyquad, n=10", 3.376327e-2),
        ];
        let ps = problems();
        let get = |name: &str| {
            ps.iter()
                .find(|p| p.name == name)
                .unwrap_or_else(|| panic!("{name}"))
        };
        for (name, f0) in want {
            let p = get(name);
            let f = sum_sq(p, &p.start);
            assert!(
                (f - f0).abs() <= 1e-6 * f0,
                "{name}: f(x0) = {f}, literature {f0}"
            );
        }
        // Points of the literature where f takes a listed value.
        let at: &[(&str, &[f64], usize)] = &[
            (
                "(2) Freudenstein and Roth",
                &[11.412_778_921_978_1, -0.896_805_259_983_574_1],
                1,
            ),
            (
                "(6) Jennrich and Sampson, m=10",
                &[0.257_825_213_568_616_2; 2],
                0,
            ),
            (
                "(8) Bard",
                &[
                    0.082_410_560_054_765_16,
                    1.133_036_079_606_067_7,
                    2.343_695_191_337_965_8,
                ],
                0,
            ),
            ("(8) Bard", &[0.840_666_666_666_666_7, -1e15, -1e15], 1),
            (
                "(15) Kowalik and Osborne",
                &[
                    0.192_806_934_016_477_58,
                    0.191_282_330_307_896_46,
                    0.123_056_503_387_043_74,
                    0.136_062_331_523_407_3,
                ],
                0,
            ),
            (
                "(10) Meyer",
                &[
                    0.005_609_636_453_940_975,
                    6_181.346_349_155_75,
                    345.223_634_733_679_55,
                ],
                0,
            ),
            (
                "(20) Watson, n=6",
                &[
                    -0.015_725_085_958_146_96,
                    1.012_434_869_225_148_8,
                    -0.232_991_618_229_606_84,
                    1.260_430_060_731_229_8,
                    -1.513_728_886_902_551_8,
                    0.992_996_419_227_757_3,
                ],
                0,
            ),
            (
                "(16) Brown and Dennis, m=20",
                &[
                    -11.594_439_969_349_615,
                    13.203_630_099_554_186,
                    -0.403_439_439_437_810_74,
                    0.236_778_775_860_315_1,
                ],
                0,
            ),
            (
                "(17) Osborne 1",
                &[
                    0.375_410_052_538_704_85,
                    1.935_846_934_707_712_5,
                    -1.464_687_159_837_940_3,
                    0.012_867_534_697_214_533,
                    0.022_122_699_602_996_29,
                ],
                0,
            ),
            (
                "(19) Osborne 2",
                &[
                    1.309_977_155_517_491_3,
                    0.431_553_795_562_227_2,
                    0.633_661_698_669_376_5,
                    0.599_430_534_429_309_8,
                    0.754_183_230_480_270_4,
                    0.904_288_575_962_244_1,
                    1.365_811_821_857_166,
                    4.823_698_851_312_894,
                    2.398_684_862_961_737,
                    4.568_874_597_996_633,
                    5.675_341_470_445_994,
                ],
                0,
            ),
            (
                "(35) Chebyquad, n=10",
                &[
                    0.074_748_167_091_523_99,
                    0.171_518_177_957_865_92,
                    0.286_434_154_544_825_85,
                    0.359_646_450_539_329_14,
                    0.470_750_526_278_371_6,
                    0.616_738_335_530_402_9,
                    0.616_738_336_783_729_4,
                    0.799_810_803_124_188_3,
                    0.844_854_641_539_109,
                    0.967_006_627_462_827_5,
                ],
                0,
            ),
        ];
        for (name, x, k) in at {
            let p = get(name);
            let (f, want) = (sum_sq(p, x), p.minima[*k]);
            assert!(
                (f - want).abs() <= 1e-9 * want,
                "{name}: f = {f}, listed {want}"
            );
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let eps = f64::EPSILON;
        for p in &problems() {
            let (m, n) = (p.m, p.n);
            for x in test_points(p) {
                let mut jac = vec![0.0; m * n];
                (p.jacobian)(&x, &mut jac);
                let mut r0 = vec![0.0; m];
                (p.residuals)(&x, &mut r0);
                for k in 0..n {
                    let h = 1e-4 * x[k].abs().max(1.0);
                    // Fourth-order central difference:
                    // [8 (r(+h) - r(-h)) - (r(+2h) - r(-2h))] / 12h.
                    let mut rs = [vec![0.0; m], vec![0.0; m], vec![0.0; m], vec![0.0; m]];
                    for (s, step) in [h, -h, 2.0 * h, -2.0 * h].iter().enumerate() {
                        let mut xs = x.clone();
                        xs[k] += step;
                        (p.residuals)(&xs, &mut rs[s]);
                    }
                    for i in 0..m {
                        let fd = (8.0 * (rs[0][i] - rs[1][i]) - (rs[2][i] - rs[3][i])) / (12.0 * h);
                        let an = jac[i * n + k];
                        // Relative 1e-6, plus the rounding floor of the difference quotient
                        // (for residuals of order one or more).
                        let scale = rs.iter().map(|r| r[i].abs()).fold(r0[i].abs(), f64::max);
                        let tol = 1e-6 * an.abs() + 20.0 * eps * scale.max(1.0) / h;
                        assert!(
                            (fd - an).abs() <= tol,
                            "{}: dr_{i}/dx_{k} at {x:?}: analytic {an}, finite difference {fd}",
                            p.name
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn closed_form_minimisers_give_the_listed_minimum() {
        let mut checked = 0;
        for p in &problems() {
            if let Some(xm) = &p.minimiser {
                let f = sum_sq(p, xm);
                let want = p.minima[0];
                assert!(
                    (f - want).abs() <= 1e-10 * want.max(1.0),
                    "{}: f(minimiser) = {f}, listed {want}",
                    p.name
                );
                checked += 1;
            }
        }
        assert!(checked >= 20);
    }

    #[test]
    fn other_closed_form_values() {
        let ps = problems();
        let get = |name: &str| ps.iter().find(|p| p.name == name).unwrap();
        // (12): (10, 1, -1) and x1 = x2, x3 = 0 are also zeros.
        let p = get("(12) Box three-dimensional, m=10");
        assert!(sum_sq(p, &[10.0, 1.0, -1.0]) < 1e-28);
        assert!(sum_sq(p, &[3.7, 3.7, 0.0]) == 0.0);
        // (27): f = 1 at (0, ..., 0, n + 1); f = 0 at (a, ..., a, a^(1-n)) for the other root.
        for n in [10usize, 30, 40] {
            let p = get(&format!("(27) Brown almost-linear, n={n}"));
            let mut x = vec![0.0; n];
            x[n - 1] = (n + 1) as f64;
            assert!((sum_sq(p, &x) - 1.0).abs() < 1e-12);
        }
        let p = get("(27) Brown almost-linear, n=10");
        // Root a != 1 of 10 a^10 - 11 a^9 + 1 = 0 in (0, 1), by bisection.
        let g = |a: f64| 10.0 * a.powi(10) - 11.0 * a.powi(9) + 1.0;
        let (mut lo, mut hi) = (0.5, 0.99);
        assert!(g(lo) > 0.0 && g(hi) < 0.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if g(mid) > 0.0 {
                lo = mid
            } else {
                hi = mid
            }
        }
        let a = 0.5 * (lo + hi);
        let mut x = vec![a; 10];
        x[9] = a.powi(-9);
        assert!(sum_sq(p, &x) < 1e-20);
    }
}
