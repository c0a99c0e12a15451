//! Closed-form starting values for camera calibration: the lens from views of a planar board,
//! each board's pose in the camera, and the camera's (or the board's) place on the robot.
//!
//! # Conventions
//!
//! OpenCV's: the camera frame has z along the optical axis (out of the lens, into the scene), x
//! to the right of the image and y down it. A pinhole with focal lengths `fx`, `fy` and
//! principal point `cx`, `cy` in pixels, zero skew, and the plumb-bob distortion `k1, k2, p1,
//! p2, k3` in OpenCV's order and formula ([`Lens::project_normalized`]). The board's points lie
//! in its plane z = 0 at `(x, y)` in metres. Poses are rigid transforms named `T_a_b`: frame
//! `b` expressed in frame `a` (a point's coordinates in `b` taken to `a`). Units: metres,
//! radians, pixels.
//!
//! # Pipeline and sources
//!
//! 1. [`Lens::undistort`] takes pixels to undistorted normalized coordinates (fixed-point
//!    iteration as in OpenCV's `undistortPoints`, then Newton steps).
//! 2. [`homography`]: the plane-to-image homography by the normalized direct linear transform
//!    (Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., algorithm 4.2), then Gauss-Newton
//!    steps on the image error.
//! 3. [`intrinsics_zhang`]: `fx, fy, cx, cy` from two or more homographies (Zhang, "A flexible
//!    new technique for camera calibration", IEEE TPAMI 22(11), 2000, section 3.1, with the
//!    skew fixed at zero).
//! 4. [`board_pose`] / [`board_pose_normalized`]: `T_camera_board` from a homography and the
//!    intrinsics (Zhang 2000, section 3.1, with the rotation made orthonormal by SVD as in his
//!    appendix C).
//! 5. [`hand_eye_ax_yb`]: robot-world/hand-eye `A_i X = Y B_i` from absolute poses (the
//!    Kronecker-product formulation of Shah, "Solving the robot-world/hand-eye calibration
//!    problem using the Kronecker product", ASME J. Mechanisms Robotics 5(3), 2013), and
//!    [`hand_eye_ax_xb`]: hand-eye `A X = X B` from relative motions (Park & Martin, "Robot
//!    sensor calibration: solving AX = XB on the Euclidean group", IEEE T-RA 10(5), 1994), with
//!    [`relative_motions_eye_in_hand`] / [`relative_motions_eye_to_hand`] making the motions.
//!
//! Starting from nothing, a caller takes the distortion as zero, makes one [`homography`] per
//! view from the raw pixels, [`intrinsics_zhang`] from all of them, [`board_pose`] per view, and
//! then [`hand_eye_ax_yb`] with the robot's forward kinematics; the fit refines everything,
//! distortion included, on the pixels. With a lens already known (distortion too), the
//! homographies come from [`Lens::undistort`]ed points and [`board_pose_normalized`] gives the
//! poses.
//!
//! Every function returns `None` rather than panic or produce a non-finite number: on
//! non-finite input, too few data, or data that does not determine the answer (collinear
//! points, parallel boards, rotations about one axis, identical views). The rank tests use
//! [`RANK_TOL`]; data that is nearly but not exactly degenerate passes them and gives a poor
//! start, which the caller's fit must judge. These are starting values only: the fit that
//! follows minimises the pixel error over all of them together.

use nalgebra::{
    DMatrix, DVector, Dyn, Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3,
    SVD,
};

/// Relative motions `(A, B)`, pair by pair, for [`hand_eye_ax_xb`].
// A second formulation the tests check the production path against.
#[cfg(test)]
pub(crate) type Motions = (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>);

/// `a > b`, false when either is NaN (the refusals below read `!exceeds(..)` so that NaN is
/// refused too).
fn exceeds(a: f64, b: f64) -> bool {
    a > b
}

/// A linear system's smallest kept singular value must exceed this fraction of its largest;
/// below it the data is taken as degenerate (the solution not unique). Exactly degenerate
/// data gives ratios near 1e-16; usable views give 1e-3 and more.
pub(crate) const RANK_TOL: f64 = 1e-8;

/// Relative motions whose rotation angle is within this of pi are left out of
/// [`hand_eye_ax_xb`]: the logarithm's axis sign is ambiguous there (radians).
// A second formulation the tests check the production path against.
#[cfg(test)]
const NEAR_PI: f64 = 1e-2;

/// The iteration cap of the SVDs (nalgebra's implicit-shift QR; 3 to 30 sweeps are typical).
const SVD_ITERATIONS: usize = 1000;

/// A camera's pinhole and plumb-bob distortion, OpenCV's model with zero skew.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lens {
    /// Focal length along x (pixels).
    pub fx: f64,
    /// Focal length along y (pixels).
    pub fy: f64,
    /// Principal point, x (pixels).
    pub cx: f64,
    /// Principal point, y (pixels).
    pub cy: f64,
    /// `[k1, k2, p1, p2, k3]` in OpenCV's order (dimensionless, on normalized coordinates).
    pub distortion: [f64; 5],
}

impl Lens {
    /// The distortion map on normalized coordinates and its Jacobian `[[dx'/dx, dx'/dy],
    /// [dy'/dx, dy'/dy]]`.
    fn distort(&self, x: f64, y: f64) -> ([f64; 2], [[f64; 2]; 2]) {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // d radial / d r2.
        let dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        let cross = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        let jacobian = [
            [
                radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
                cross,
            ],
            [
                cross,
                radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ];
        ([xd, yd], jacobian)
    }

    /// Normalized image coordinates `(x, y) = (X/Z, Y/Z)` of a point in the camera frame to
    /// pixels, through OpenCV's plumb bob: `r2 = x² + y²`, `radial = 1 + k1 r2 + k2 r2² + k3
    /// r2³`, `x' = x radial + 2 p1 x y + p2 (r2 + 2 x²)`, `y' = y radial + p1 (r2 + 2 y²) + 2
    /// p2 x y`, `u = fx x' + cx`, `v = fy y' + cy`.
    // A second formulation the tests check the production path against.
    #[cfg(test)]
    pub(crate) fn project_normalized(&self, x: f64, y: f64) -> [f64; 2] {
        let ([xd, yd], _) = self.distort(x, y);
        [self.fx * xd + self.cx, self.fy * yd + self.cy]
    }

    /// The inverse of [`Lens::project_normalized`]: pixels `(u, v)` to undistorted normalized
    /// coordinates `(x, y)`.
    ///
    /// Fixed-point iteration as OpenCV's `undistortPoints` (`x = (x_d - tangential) /
    /// radial`), then Newton steps on the distortion map. `None` when the lens is not usable
    /// (non-finite, focal lengths not positive), the input is not finite, the distortion map
    /// is not reached to 1e-12 in normalized coordinates (6e-10 px at fx = 600), or the
    /// solution lies where the map folds over (Jacobian determinant not positive: beyond the
    /// radius where strong barrel distortion turns back, a pixel has no physical preimage).
    pub(crate) fn undistort(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        let finite = [self.fx, self.fy, self.cx, self.cy, u, v]
            .iter()
            .chain(self.distortion.iter())
            .all(|x| x.is_finite());
        if !(finite && self.fx > 0.0 && self.fy > 0.0) {
            return None;
        }
        let target = [(u - self.cx) / self.fx, (v - self.cy) / self.fy];
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (mut x, mut y) = (target[0], target[1]);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            if !(radial.is_finite() && radial.abs() > 1e-12) {
                break;
            }
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            let (nx, ny) = ((target[0] - dx) / radial, (target[1] - dy) / radial);
            if !(nx.is_finite() && ny.is_finite()) {
                break;
            }
            let change = (nx - x).abs().max((ny - y).abs());
            (x, y) = (nx, ny);
            if change < 1e-14 {
                break;
            }
        }
        // Newton from wherever the fixed point got to (OpenCV stops there; its iteration
        // converges only linearly, and not at all for strong distortion).
        if !(x.is_finite() && y.is_finite()) {
            (x, y) = (target[0], target[1]);
        }
        for _ in 0..30 {
            let ([xd, yd], j) = self.distort(x, y);
            let (ex, ey) = (xd - target[0], yd - target[1]);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if !(ex.is_finite() && ey.is_finite() && det.is_finite()) {
                return None;
            }
            if ex.abs().max(ey.abs()) <= 1e-12 {
                return (det > 0.0).then_some([x, y]);
            }
            if det.abs() < 1e-300 {
                return None;
            }
            x -= (j[1][1] * ex - j[0][1] * ey) / det;
            y -= (-j[1][0] * ex + j[0][0] * ey) / det;
        }
        None
    }
}

/// The SVD of a finite matrix with at least as many rows as columns, singular values in
/// descending order; `None` on non-finite entries or when the iteration does not converge.
fn svd(m: DMatrix<f64>) -> Option<SVD<f64, Dyn, Dyn>> {
    if m.nrows() < m.ncols() || !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    let svd = SVD::try_new(m, true, true, f64::EPSILON, SVD_ITERATIONS)?;
    svd.singular_values
        .iter()
        .all(|s| s.is_finite())
        .then_some(svd)
}

/// The unit vector spanning the null space of `m` (rows >= columns), `None` unless the null
/// space is one-dimensional to [`RANK_TOL`] (the second-smallest singular value above it).
fn null_vector(m: DMatrix<f64>) -> Option<DVector<f64>> {
    let n = m.ncols();
    let s = svd(m)?;
    let sv = &s.singular_values;
    if !exceeds(sv[n - 2], RANK_TOL * sv[0]) {
        return None;
    }
    let v_t = s.v_t.as_ref()?;
    Some(v_t.row(n - 1).transpose())
}

/// The least-squares solution of `m x = rhs`, `None` unless `m` has full column rank to
/// [`RANK_TOL`].
fn least_squares(m: DMatrix<f64>, rhs: &DVector<f64>) -> Option<DVector<f64>> {
    let n = m.ncols();
    if !rhs.iter().all(|x| x.is_finite()) {
        return None;
    }
    let s = svd(m)?;
    let sv = &s.singular_values;
    if !exceeds(sv[n - 1], RANK_TOL * sv[0]) {
        return None;
    }
    let x = s.solve(rhs, 0.0).ok()?;
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The rotation nearest to `m` in the Frobenius norm (`U diag(1, 1, det(U V^T)) V^T`), `None`
/// when `m` is not finite or has rank below 2 (the nearest rotation is then not unique).
fn nearest_rotation(m: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    if !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    let s = SVD::try_new(*m, true, true, f64::EPSILON, SVD_ITERATIONS)?;
    let sv = s.singular_values;
    if !exceeds(sv[1], RANK_TOL * sv[0]) || !sv.iter().all(|x| x.is_finite()) {
        return None;
    }
    let (u, v_t) = (s.u?, s.v_t?);
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    r.iter()
        .all(|x| x.is_finite())
        .then(|| Rotation3::from_matrix_unchecked(r))
}

fn isometry(r: &Rotation3<f64>, t: Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(r),
    )
}

fn finite_isometry(p: &Isometry3<f64>) -> bool {
    p.translation.vector.iter().all(|x| x.is_finite())
        && p.rotation.coords.iter().all(|x| x.is_finite())
}

/// Hartley's normalizing similarity of 2-D points: centroid to the origin, mean distance from
/// it sqrt(2). `None` when the points are not finite, coincide, or are collinear (the smaller
/// principal second moment below [`RANK_TOL`] times the larger).
fn normalizing_similarity(points: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    let n = points.len() as f64;
    if points.is_empty() || !points.iter().flatten().all(|x| x.is_finite()) {
        return None;
    }
    let cx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let mean_distance = points
        .iter()
        .map(|p| (p[0] - cx).hypot(p[1] - cy))
        .sum::<f64>()
        / n;
    if !(mean_distance > 0.0 && mean_distance.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean_distance;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (x, y) = (s * (p[0] - cx), s * (p[1] - cy));
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    // The eigenvalues of [[sxx, sxy], [sxy, syy]].
    let half_trace = 0.5 * (sxx + syy);
    let radius = (0.5 * (sxx - syy)).hypot(sxy);
    let (small, large) = (half_trace - radius, half_trace + radius);
    if !exceeds(small, RANK_TOL * large) {
        return None;
    }
    Some(Matrix3::new(
        s,
        0.0,
        -s * cx,
        0.0,
        s,
        -s * cy,
        0.0,
        0.0,
        1.0,
    ))
}

fn apply(h: &Matrix3<f64>, p: [f64; 2]) -> Vector3<f64> {
    h * Vector3::new(p[0], p[1], 1.0)
}

/// The sum of squared image errors of `h` and whether every point maps with a positive third
/// coordinate (in front of the camera under this sign of `h`).
fn image_error(h: &Matrix3<f64>, plane: &[[f64; 2]], image: &[[f64; 2]]) -> Option<f64> {
    let mut sum = 0.0;
    for (p, q) in plane.iter().zip(image) {
        let w = apply(h, *p);
        if !exceeds(w.z, 0.0) {
            return None;
        }
        sum += (w.x / w.z - q[0]).powi(2) + (w.y / w.z - q[1]).powi(2);
    }
    sum.is_finite().then_some(sum)
}

/// Gauss-Newton on the image error of a homography (points already normalized), the step of
/// least norm in the 9 entries (the scale direction is free). Steps that do not lower the
/// error are refused.
fn refine_homography(h: Matrix3<f64>, plane: &[[f64; 2]], image: &[[f64; 2]]) -> Matrix3<f64> {
    let Some(mut cost) = image_error(&h, plane, image) else {
        return h;
    };
    let mut h = h;
    for _ in 0..5 {
        let n = plane.len();
        let mut j = DMatrix::zeros(2 * n, 9);
        let mut r = DVector::zeros(2 * n);
        for (k, (p, q)) in plane.iter().zip(image).enumerate() {
            let w = apply(&h, *p);
            let (u, v) = (w.x / w.z, w.y / w.z);
            r[2 * k] = u - q[0];
            r[2 * k + 1] = v - q[1];
            let basis = [p[0], p[1], 1.0];
            for c in 0..3 {
                j[(2 * k, c)] = basis[c] / w.z;
                j[(2 * k, 6 + c)] = -u * basis[c] / w.z;
                j[(2 * k + 1, 3 + c)] = basis[c] / w.z;
                j[(2 * k + 1, 6 + c)] = -v * basis[c] / w.z;
            }
        }
        let Some(s) = svd(j) else {
            return h;
        };
        let Ok(step) = s.solve(&r, RANK_TOL * s.singular_values[0]) else {
            return h;
        };
        let mut trial = h;
        for (k, value) in trial.iter_mut().enumerate() {
            // Row-major order of the Jacobian's columns against nalgebra's column-major storage.
            let (row, col) = (k % 3, k / 3);
            *value -= step[3 * row + col];
        }
        match image_error(&trial, plane, image) {
            Some(c) if c < cost => {
                let done = c > cost * (1.0 - 1e-10);
                (h, cost) = (trial, c);
                if done {
                    break;
                }
            }
            _ => break,
        }
    }
    h
}

/// The homography `H` taking board-plane points `(x, y)` (metres) to image points (undistorted:
/// pixels, or normalized coordinates from [`Lens::undistort`]): `image ~ H [x, y, 1]^T`.
///
/// The normalized direct linear transform (Hartley & Zisserman, algorithm 4.2: both point sets
/// moved to centroid 0 and mean distance sqrt 2, the null vector of the stacked 2n x 9 system by
/// SVD, the normalisations undone), then up to 5 Gauss-Newton steps on the image error
/// (each kept only when it lowers it). Scaled so that `H[(2,2)] = 1` when that entry is
/// positive and not negligible (above 1e-9 of the norm; the board origin's image is then `H`'s
/// last column); otherwise to unit Frobenius norm. Either way every given point maps with a
/// positive third coordinate.
///
/// `None` on fewer than 4 points, different lengths, non-finite numbers, coincident or
/// collinear points (in either set), a solution that is not unique, or points that would lie
/// on both sides of the camera (no single view shows them).
pub(crate) fn homography(plane: &[[f64; 2]], image: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    let n = plane.len();
    if n < 4 || image.len() != n {
        return None;
    }
    let tp = normalizing_similarity(plane)?;
    let ti = normalizing_similarity(image)?;
    let norm = |t: &Matrix3<f64>, p: &[f64; 2]| {
        let w = apply(t, *p);
        [w.x, w.y]
    };
    let plane_n: Vec<[f64; 2]> = plane.iter().map(|p| norm(&tp, p)).collect();
    let image_n: Vec<[f64; 2]> = image.iter().map(|p| norm(&ti, p)).collect();
    // Padded with zero rows to 9 (the SVD's right vectors need rows >= columns).
    let mut a = DMatrix::zeros((2 * n).max(9), 9);
    for (k, (p, q)) in plane_n.iter().zip(&image_n).enumerate() {
        let basis = [p[0], p[1], 1.0];
        for c in 0..3 {
            a[(2 * k, c)] = basis[c];
            a[(2 * k, 6 + c)] = -q[0] * basis[c];
            a[(2 * k + 1, 3 + c)] = basis[c];
            a[(2 * k + 1, 6 + c)] = -q[1] * basis[c];
        }
    }
    let h = null_vector(a)?;
    let mut hn = Matrix3::from_row_slice(h.as_slice());
    // The sign that puts the points in front (the third coordinate positive).
    let w: Vec<f64> = plane_n.iter().map(|p| apply(&hn, *p).z).collect();
    if w.iter().all(|w| *w < 0.0) {
        hn = -hn;
    } else if !w.iter().all(|w| *w > 0.0) {
        return None;
    }
    let hn = refine_homography(hn, &plane_n, &image_n);
    let ti_inv = ti.try_inverse()?;
    let h = ti_inv * hn * tp;
    let frobenius = h.norm();
    if !(frobenius > 0.0 && frobenius.is_finite()) {
        return None;
    }
    let h = h / frobenius;
    let h = if h[(2, 2)] > 1e-9 { h / h[(2, 2)] } else { h };
    h.iter().all(|x| x.is_finite()).then_some(h)
}

/// Zhang's `v_ij` row for the unknowns `[B11, B22, B13, B23, B33]` of `B = K^-T K^-1` with
/// `B12 = 0` (zero skew): `h_i^T B h_j` for columns `i`, `j` of `h`.
fn zhang_row(h: &Matrix3<f64>, i: usize, j: usize) -> [f64; 5] {
    let (a, b) = (h.column(i), h.column(j));
    [
        a[0] * b[0],
        a[1] * b[1],
        a[2] * b[0] + a[0] * b[2],
        a[2] * b[1] + a[1] * b[2],
        a[2] * b[2],
    ]
}

/// The intrinsics `[fx, fy, cx, cy]` (pixels, zero skew) from plane-to-pixel homographies of
/// two or more views of a planar board (Zhang 2000, section 3.1).
///
/// Each view gives the two constraints `h1^T B h2 = 0` and `h1^T B h1 = h2^T B h2` on the image
/// of the absolute conic `B = K^-T K^-1`; zero skew sets `B12 = 0`, leaving 5 unknowns up to
/// scale, so two views in general position suffice (three and more in practice, for noise).
/// For conditioning the pixels are first moved by a similarity (centred on the mean of the
/// board origins' images, scaled by their RMS distance from pixel (0, 0)) and each homography
/// scaled to unit norm; the similarity is undone on `K`.
///
/// `None` on fewer than 2 homographies, non-finite entries, constraints that do not determine
/// `B` (all boards parallel, e.g. fronto-parallel or only rotated about their normal; identical
/// views), or `B` not positive definite (noise on nearly degenerate views).
pub(crate) fn intrinsics_zhang(homographies: &[Matrix3<f64>]) -> Option<[f64; 4]> {
    if homographies.len() < 2 || !homographies.iter().all(|h| h.iter().all(|x| x.is_finite())) {
        return None;
    }
    // The conditioning similarity: from the origins' images where they are finite.
    let origins: Vec<[f64; 2]> = homographies
        .iter()
        .filter(|h| h[(2, 2)].abs() > 1e-12 * h.norm())
        .map(|h| [h[(0, 2)] / h[(2, 2)], h[(1, 2)] / h[(2, 2)]])
        .filter(|o| o[0].is_finite() && o[1].is_finite())
        .collect();
    let (mut c, mut s) = ([0.0, 0.0], 1.0);
    if !origins.is_empty() {
        let m = origins.len() as f64;
        let rms = (origins
            .iter()
            .map(|o| o[0] * o[0] + o[1] * o[1])
            .sum::<f64>()
            / m)
            .sqrt();
        if rms > 0.0 && rms.is_finite() {
            c = [
                origins.iter().map(|o| o[0]).sum::<f64>() / m,
                origins.iter().map(|o| o[1]).sum::<f64>() / m,
            ];
            s = 1.0 / rms;
        }
    }
    let n_sim = Matrix3::new(s, 0.0, -s * c[0], 0.0, s, -s * c[1], 0.0, 0.0, 1.0);
    let n = homographies.len();
    let mut v = DMatrix::zeros((2 * n).max(5), 5);
    for (k, h) in homographies.iter().enumerate() {
        let h = n_sim * h;
        let norm = h.norm();
        if !(norm > 0.0 && norm.is_finite()) {
            return None;
        }
        let h = h / norm;
        let (v12, v11, v22) = (
            zhang_row(&h, 0, 1),
            zhang_row(&h, 0, 0),
            zhang_row(&h, 1, 1),
        );
        for col in 0..5 {
            v[(2 * k, col)] = v12[col];
            v[(2 * k + 1, col)] = v11[col] - v22[col];
        }
    }
    let b = null_vector(v)?;
    let b = if b[0] < 0.0 { -b } else { b };
    let (b11, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4]);
    let tiny = 1e-12 * b.amax();
    if !(b11 > tiny && b22 > tiny) {
        return None;
    }
    // B = lambda K^-T K^-1 with K^-1 = [[1/fx, 0, -cx/fx], [0, 1/fy, -cy/fy], [0, 0, 1]].
    let lambda = b33 - b13 * b13 / b11 - b23 * b23 / b22;
    if !exceeds(lambda, tiny) {
        return None;
    }
    let (fx, fy) = ((lambda / b11).sqrt() / s, (lambda / b22).sqrt() / s);
    let (cx, cy) = (-b13 / b11 / s + c[0], -b23 / b22 / s + c[1]);
    let k = [fx, fy, cx, cy];
    (k.iter().all(|x| x.is_finite()) && fx > 0.0 && fy > 0.0).then_some(k)
}

/// The board's pose in the camera, `T_camera_board`, from a plane-to-pixel homography and the
/// intrinsics `lens_k = [fx, fy, cx, cy]` (distortion already removed from the pixels):
/// [`board_pose_normalized`] of `K^-1 H`. `None` when `fx` or `fy` is not positive or not
/// finite, or as [`board_pose_normalized`].
// A second formulation the tests check the production path against.
#[cfg(test)]
pub(crate) fn board_pose(lens_k: [f64; 4], h: &Matrix3<f64>) -> Option<Isometry3<f64>> {
    let [fx, fy, cx, cy] = lens_k;
    if !(lens_k.iter().all(|x| x.is_finite()) && fx > 0.0 && fy > 0.0) {
        return None;
    }
    let k_inv = Matrix3::new(
        1.0 / fx,
        0.0,
        -cx / fx,
        0.0,
        1.0 / fy,
        -cy / fy,
        0.0,
        0.0,
        1.0,
    );
    board_pose_normalized(&(k_inv * h))
}

/// The board's pose in the camera, `T_camera_board`, from a homography taking board points
/// (metres) to normalized image coordinates (`X/Z, Y/Z`, e.g. from [`Lens::undistort`]).
///
/// `H ~ [r1 r2 t]`: scaled by the inverse mean of the first two columns' norms, the sign chosen
/// so that the board origin is in front of the camera (`t.z > 0`), `r3 = r1 x r2`, and the
/// rotation made the nearest proper rotation by SVD (Zhang 2000, appendix C). Any scale and
/// sign of `h` give the same pose. `None` on non-finite entries, a zero column, or the board
/// origin in the camera's focal plane (`|t.z|` below 1e-12 of `|t|`: no view of it).
pub(crate) fn board_pose_normalized(h: &Matrix3<f64>) -> Option<Isometry3<f64>> {
    if !h.iter().all(|x| x.is_finite()) {
        return None;
    }
    let (a1, a2, a3) = (h.column(0), h.column(1), h.column(2));
    let (n1, n2) = (a1.norm(), a2.norm());
    if !(n1 > 0.0 && n2 > 0.0 && (n1 + n2).is_finite()) {
        return None;
    }
    let scale = 2.0 / (n1 + n2);
    let (mut r1, mut r2, mut t) = (a1 * scale, a2 * scale, a3 * scale);
    if !exceeds(t.z.abs(), 1e-12 * t.norm()) {
        return None;
    }
    if t.z < 0.0 {
        (r1, r2, t) = (-r1, -r2, -t);
    }
    let r3 = r1.cross(&r2);
    let r = nearest_rotation(&Matrix3::from_columns(&[r1, r2, r3]))?;
    Some(isometry(&r, t))
}

/// `X` and `Y` minimising `A_i X = Y B_i` (i = 1..n, n >= 3): robot-world/hand-eye calibration
/// from absolute poses.
///
/// Rotations: `R_Ai R_X = R_Y R_Bi` is linear in `vec(R_X), vec(R_Y)`: `(I ⊗ R_Ai) vec(R_X) -
/// (R_Bi^T ⊗ I) vec(R_Y) = 0`; the stacked 9n x 18 system's null vector (SVD) is scaled to
/// `det = +1` and each half projected onto SO(3) (Shah 2013). Translations: the linear least
/// squares of `R_Ai t_X - t_Y = R_Y t_Bi - t_Ai`.
///
/// With `E_i = T_world_ee` from forward kinematics and `P_i = T_camera_board` from
/// [`board_pose`]:
/// - eye-in-hand (camera on the end effector, board fixed in the world): `X = T_ee_camera`,
///   `Y = T_world_board`, `E_i X P_i = Y`, so `A_i = E_i`, `B_i = P_i^-1`;
/// - eye-to-hand (camera fixed, board on the end effector): `X = T_ee_board`, `Y =
///   T_world_camera`, `E_i X = Y P_i`, so `A_i = E_i`, `B_i = P_i`.
///
/// `None` on fewer than 3 pairs, different lengths, non-finite poses, or poses that do not
/// determine `X` and `Y` (rotations all about one axis, identical poses).
pub(crate) fn hand_eye_ax_yb(
    a: &[Isometry3<f64>],
    b: &[Isometry3<f64>],
) -> Option<(Isometry3<f64>, Isometry3<f64>)> {
    let n = a.len();
    if n < 3 || b.len() != n || !a.iter().chain(b).all(finite_isometry) {
        return None;
    }
    let rotation = |p: &Isometry3<f64>| p.rotation.to_rotation_matrix().into_inner();
    let mut m = DMatrix::zeros(9 * n, 18);
    for (i, (ai, bi)) in a.iter().zip(b).enumerate() {
        let (ra, rb) = (rotation(ai), rotation(bi));
        for p in 0..3 {
            // Column p of R_A R_X is R_A times column p of R_X.
            m.view_mut((9 * i + 3 * p, 3 * p), (3, 3)).copy_from(&ra);
            // Column p of R_Y R_B is sum_q R_B[q, p] times column q of R_Y.
            for q in 0..3 {
                for d in 0..3 {
                    m[(9 * i + 3 * p + d, 9 + 3 * q + d)] = -rb[(q, p)];
                }
            }
        }
    }
    let x = null_vector(m)?;
    let rx = Matrix3::from_column_slice(&x.as_slice()[..9]);
    let ry = Matrix3::from_column_slice(&x.as_slice()[9..]);
    let det = rx.determinant();
    if !exceeds(det.abs(), 1e-12) {
        return None;
    }
    let scale = det.signum() / det.abs().cbrt();
    let mut rx = nearest_rotation(&(rx * scale))?;
    let mut ry = nearest_rotation(&(ry * scale))?;
    // The projections onto SO(3) leave the pair off the constrained least squares of sum |R_Ai
    // R_X - R_Y R_Bi|²; alternating the two Procrustes solutions (each exact given the other)
    // descends to it.
    let rotations: Vec<(Matrix3<f64>, Matrix3<f64>)> = a
        .iter()
        .zip(b)
        .map(|(ai, bi)| (rotation(ai), rotation(bi)))
        .collect();
    for _ in 0..100 {
        let sum_x: Matrix3<f64> = rotations
            .iter()
            .map(|(ra, rb)| ra.transpose() * ry.matrix() * rb)
            .sum();
        let new_x = nearest_rotation(&sum_x)?;
        let sum_y: Matrix3<f64> = rotations
            .iter()
            .map(|(ra, rb)| ra * new_x.matrix() * rb.transpose())
            .sum();
        let new_y = nearest_rotation(&sum_y)?;
        let change = (new_x.matrix() - rx.matrix()).norm() + (new_y.matrix() - ry.matrix()).norm();
        (rx, ry) = (new_x, new_y);
        if change < 1e-13 {
            break;
        }
    }
    let mut m = DMatrix::zeros(3 * n, 6);
    let mut rhs = DVector::zeros(3 * n);
    for (i, (ai, bi)) in a.iter().zip(b).enumerate() {
        m.view_mut((3 * i, 0), (3, 3)).copy_from(&rotation(ai));
        m.view_mut((3 * i, 3), (3, 3))
            .copy_from(&(-Matrix3::identity()));
        let r = ry * bi.translation.vector - ai.translation.vector;
        rhs.rows_mut(3 * i, 3).copy_from(&r);
    }
    let t = least_squares(m, &rhs)?;
    Some((
        isometry(&rx, Vector3::new(t[0], t[1], t[2])),
        isometry(&ry, Vector3::new(t[3], t[4], t[5])),
    ))
}

/// `X` minimising `A_i X = X B_i` for relative motions (i = 1..n, n >= 2; Park & Martin 1994).
///
/// Rotation: `R_Ai = R_X R_Bi R_X^T`, so the log maps satisfy `alpha_i = R_X beta_i`; `R_X` is
/// the rotation nearest to `sum alpha_i beta_i^T` (SVD with `det = +1`; Park & Martin's `(M^T
/// M)^-1/2 M^T` where it is proper). Motions whose angle is within 0.01 rad of pi are left out
/// (the axis sign is ambiguous there). Translation: the linear least squares of `(R_Ai - I)
/// t_X = R_X t_Bi - t_Ai`.
///
/// `None` on fewer than 2 motions, different lengths, non-finite poses, or motions that do not
/// determine `X` (fewer than two distinct rotation axes, e.g. all about one axis).
// A second formulation the tests check the production path against.
#[cfg(test)]
pub(crate) fn hand_eye_ax_xb(a: &[Isometry3<f64>], b: &[Isometry3<f64>]) -> Option<Isometry3<f64>> {
    let n = a.len();
    if n < 2 || b.len() != n || !a.iter().chain(b).all(finite_isometry) {
        return None;
    }
    let limit = std::f64::consts::PI - NEAR_PI;
    let mut m = Matrix3::zeros();
    let mut used = Vec::with_capacity(n);
    for (ai, bi) in a.iter().zip(b) {
        let (alpha, beta) = (ai.rotation.scaled_axis(), bi.rotation.scaled_axis());
        if alpha.norm() > limit || beta.norm() > limit {
            continue;
        }
        m += alpha * beta.transpose();
        used.push((ai, bi));
    }
    if used.len() < 2 {
        return None;
    }
    let rx = nearest_rotation(&m)?;
    let mut lhs = DMatrix::zeros(3 * used.len(), 3);
    let mut rhs = DVector::zeros(3 * used.len());
    for (i, (ai, bi)) in used.iter().enumerate() {
        let ra = ai.rotation.to_rotation_matrix().into_inner();
        lhs.view_mut((3 * i, 0), (3, 3))
            .copy_from(&(ra - Matrix3::identity()));
        let r = rx * bi.translation.vector - ai.translation.vector;
        rhs.rows_mut(3 * i, 3).copy_from(&r);
    }
    let t = least_squares(lhs, &rhs)?;
    Some(isometry(&rx, Vector3::new(t[0], t[1], t[2])))
}

/// The relative motions `(A_ij, B_ij)` of every pair `i < j` for [`hand_eye_ax_xb`] in the
/// eye-in-hand case: `E_i = T_world_ee`, `P_i = T_camera_board`, `E_i X P_i = Y` with `X =
/// T_ee_camera`, so `A_ij = E_j^-1 E_i` and `B_ij = P_j P_i^-1` satisfy `A_ij X = X B_ij`.
/// `Y = E_i X P_i` for any `i` once `X` is known. `None` on fewer than 2 poses or different
/// lengths.
// A second formulation the tests check the production path against.
#[cfg(test)]
pub(crate) fn relative_motions_eye_in_hand(
    e: &[Isometry3<f64>],
    p: &[Isometry3<f64>],
) -> Option<Motions> {
    relative_motions(e, p, |pi, pj| pj * pi.inverse())
}

/// As [`relative_motions_eye_in_hand`] for eye-to-hand: `E_i X = Y P_i` with `X =
/// T_ee_board`, `Y = T_world_camera`, so `A_ij = E_j^-1 E_i` and `B_ij = P_j^-1 P_i`.
// A second formulation the tests check the production path against.
#[cfg(test)]
pub(crate) fn relative_motions_eye_to_hand(
    e: &[Isometry3<f64>],
    p: &[Isometry3<f64>],
) -> Option<Motions> {
    relative_motions(e, p, |pi, pj| pj.inverse() * pi)
}

// A second formulation the tests check the production path against.
#[cfg(test)]
fn relative_motions(
    e: &[Isometry3<f64>],
    p: &[Isometry3<f64>],
    board: impl Fn(&Isometry3<f64>, &Isometry3<f64>) -> Isometry3<f64>,
) -> Option<Motions> {
    let n = e.len();
    if n < 2 || p.len() != n {
        return None;
    }
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for i in 0..n {
        for j in i + 1..n {
            a.push(e[j].inverse() * e[i]);
            b.push(board(&p[i], &p[j]));
        }
    }
    Some((a, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    const K_TRUE: [f64; 4] = [600.0, 610.0, 320.0, 240.0];

    /// The 9 x 6 board with 25 mm spacing (metres).
    fn board() -> Vec<[f64; 2]> {
        let mut points = Vec::new();
        for j in 0..6 {
            for i in 0..9 {
                points.push([0.025 * i as f64, 0.025 * j as f64]);
            }
        }
        points
    }

    fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
        let q: [f64; 4] = std::array::from_fn(|_| StandardNormal.sample(rng));
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]))
    }

    fn random_pose(rng: &mut ChaCha8Rng, reach: f64) -> Isometry3<f64> {
        let t = Vector3::from_fn(|_, _| rng.random_range(-reach..reach));
        Isometry3::from_parts(Translation3::from(t), random_rotation(rng))
    }

    /// A camera 0.3 to 0.5 m from the board's centre, its axis 11 to 52 degrees from the
    /// board's normal (on the board's +z side), aimed within 3 cm of the centre, rolled at
    /// random, the whole board inside the 640 x 480 image: `T_camera_board`. With `tilt =
    /// false` every camera looks straight down the normal from anywhere within 5 cm of the
    /// centre (all boards parallel to the image plane).
    fn random_view(rng: &mut ChaCha8Rng, tilt: bool) -> Isometry3<f64> {
        let centre = Vector3::new(0.1, 0.0625, 0.0);
        loop {
            let distance = rng.random_range(0.3..0.5);
            let offset = Vector3::new(
                rng.random_range(-0.03..0.03),
                rng.random_range(-0.03..0.03),
                0.0,
            );
            let (position, aim) = if tilt {
                let polar = rng.random_range(0.2..0.9f64);
                let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
                let direction = Vector3::new(
                    polar.sin() * azimuth.cos(),
                    polar.sin() * azimuth.sin(),
                    polar.cos(),
                );
                (centre + distance * direction, centre + offset)
            } else {
                let above = centre + offset * (5.0 / 3.0);
                (above + Vector3::new(0.0, 0.0, distance), above)
            };
            let z = (aim - position).normalize();
            let helper = if z.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let x0 = helper.cross(&z).normalize();
            let roll = rng.random_range(0.0..std::f64::consts::TAU);
            let x = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(z), roll) * x0;
            let y = z.cross(&x);
            let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
            let view = isometry(&r, position).inverse();
            let inside = board().into_iter().all(|q| {
                let [u, v] = pixel(K_TRUE, &view, q);
                (0.0..640.0).contains(&u) && (0.0..480.0).contains(&v)
            });
            if inside {
                return view;
            }
        }
    }

    fn pixel(k: [f64; 4], pose: &Isometry3<f64>, p: [f64; 2]) -> [f64; 2] {
        let c = pose * nalgebra::Point3::new(p[0], p[1], 0.0);
        [k[0] * c.x / c.z + k[2], k[1] * c.y / c.z + k[3]]
    }

    fn pixels(
        k: [f64; 4],
        pose: &Isometry3<f64>,
        noise: f64,
        rng: &mut ChaCha8Rng,
    ) -> Vec<[f64; 2]> {
        board()
            .into_iter()
            .map(|p| {
                let [u, v] = pixel(k, pose, p);
                let (du, dv): (f64, f64) = (StandardNormal.sample(rng), StandardNormal.sample(rng));
                [u + noise * du, v + noise * dv]
            })
            .collect()
    }

    /// Rotation angle (rad) and translation distance (m) between two poses.
    fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
        (
            a.rotation.angle_to(&b.rotation),
            (a.translation.vector - b.translation.vector).norm(),
        )
    }

    struct Scene {
        /// `T_camera_board` of each view.
        views: Vec<Isometry3<f64>>,
        /// Eye-in-hand: `T_ee_camera`.
        x: Isometry3<f64>,
        /// Eye-in-hand: `T_world_board`.
        y: Isometry3<f64>,
        /// `T_world_ee` of each view, `Y P_i^-1 X^-1`.
        ee: Vec<Isometry3<f64>>,
    }

    fn scene(seed: u64, n: usize) -> Scene {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let views: Vec<_> = (0..n).map(|_| random_view(&mut rng, true)).collect();
        let x = random_pose(&mut rng, 0.15);
        let y = random_pose(&mut rng, 1.0);
        let ee = views
            .iter()
            .map(|p| y * p.inverse() * x.inverse())
            .collect();
        Scene { views, x, y, ee }
    }

    fn max_k_error(k: [f64; 4]) -> f64 {
        k.iter()
            .zip(K_TRUE)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn project_normalized_is_opencvs_formula_term_by_term() {
        // Each coefficient alone, against the formula worked by hand at x = 0.1, y = 0.2
        // (r2 = 0.05).
        let lens = |d: [f64; 5]| Lens {
            fx: 100.0,
            fy: 200.0,
            cx: 10.0,
            cy: 20.0,
            distortion: d,
        };
        let cases = [
            ([0.0; 5], [0.1, 0.2]),
            ([0.5, 0.0, 0.0, 0.0, 0.0], [0.1 * 1.025, 0.2 * 1.025]),
            ([0.0, 0.5, 0.0, 0.0, 0.0], [0.1 * 1.00125, 0.2 * 1.00125]),
            ([0.0, 0.0, 0.0, 0.0, 8.0], [0.1 * 1.001, 0.2 * 1.001]),
            // p1: x += 2 p1 x y = 0.04 p1, y += p1 (r2 + 2 y²) = 0.13 p1.
            ([0.0, 0.0, 0.5, 0.0, 0.0], [0.1 + 0.02, 0.2 + 0.065]),
            // p2: x += p2 (r2 + 2 x²) = 0.07 p2, y += 2 p2 x y = 0.04 p2.
            ([0.0, 0.0, 0.0, 0.5, 0.0], [0.1 + 0.035, 0.2 + 0.02]),
        ];
        for (d, [xd, yd]) in cases {
            let [u, v] = lens(d).project_normalized(0.1, 0.2);
            assert!((u - (100.0 * xd + 10.0)).abs() < 1e-12, "{d:?}: u {u}");
            assert!((v - (200.0 * yd + 20.0)).abs() < 1e-12, "{d:?}: v {v}");
        }
    }

    #[test]
    fn undistort_inverts_project_normalized_over_the_image() {
        let lens = Lens {
            fx: 600.0,
            fy: 610.0,
            cx: 320.0,
            cy: 240.0,
            distortion: [-0.2, 0.05, 1e-3, -5e-4, 0.0],
        };
        let mut worst = 0.0f64;
        let mut worst_normalized = 0.0f64;
        for i in 0..=32 {
            for j in 0..=24 {
                let (u, v) = (20.0 * i as f64, 20.0 * j as f64);
                let [x, y] = lens.undistort(u, v).expect("converges inside the image");
                let [u2, v2] = lens.project_normalized(x, y);
                worst = worst.max((u2 - u).abs()).max((v2 - v).abs());
                // And the other way: normalized -> pixels -> normalized.
                let (xn, yn) = ((u - 320.0) / 600.0, (v - 240.0) / 610.0);
                let [u3, v3] = lens.project_normalized(xn, yn);
                let [x3, y3] = lens.undistort(u3, v3).expect("converges");
                worst_normalized = worst_normalized.max((x3 - xn).abs()).max((y3 - yn).abs());
            }
        }
        eprintln!("undistort round trip: {worst:.2e} px, {worst_normalized:.2e} normalized");
        // Convergence is to 1e-12 in normalized coordinates, i.e. 6.1e-10 px at fy = 610.
        assert!(worst < 1e-9, "{worst}");
        // The map's Jacobian is near 1 in the image, so the preimage is as close.
        assert!(worst_normalized < 1e-11, "{worst_normalized}");
    }

    #[test]
    fn undistort_refuses_pixels_without_a_preimage_and_bad_input() {
        // With k1 = -1 the radial map r (1 - r²) peaks at r_d = 0.385 (r = 0.577): a pixel at
        // normalized radius 0.5 has no preimage.
        let lens = Lens {
            fx: 600.0,
            fy: 600.0,
            cx: 320.0,
            cy: 240.0,
            distortion: [-1.0, 0.0, 0.0, 0.0, 0.0],
        };
        assert!(lens.undistort(320.0 + 300.0, 240.0).is_none());
        assert!(lens.undistort(320.0 + 100.0, 240.0).is_some());
        assert!(lens.undistort(f64::NAN, 240.0).is_none());
        assert!(lens.undistort(f64::INFINITY, 240.0).is_none());
        let zero = Lens { fx: 0.0, ..lens };
        assert!(zero.undistort(1.0, 1.0).is_none());
        let nan = Lens {
            distortion: [f64::NAN, 0.0, 0.0, 0.0, 0.0],
            ..lens
        };
        assert!(nan.undistort(1.0, 1.0).is_none());
    }

    #[test]
    fn noise_free_views_recover_k_poses_x_and_y() {
        let s = scene(40, 25);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let hs: Vec<Matrix3<f64>> = s
            .views
            .iter()
            .map(|p| homography(&board(), &pixels(K_TRUE, p, 0.0, &mut rng)).unwrap())
            .collect();
        // The homography reproduces the pixels it was made from.
        let mut reprojection = 0.0f64;
        for (h, p) in hs.iter().zip(&s.views) {
            for q in board() {
                let w = apply(h, q);
                let [u, v] = pixel(K_TRUE, p, q);
                reprojection = reprojection
                    .max((w.x / w.z - u).abs())
                    .max((w.y / w.z - v).abs());
            }
        }
        let k = intrinsics_zhang(&hs).unwrap();
        let k_error = max_k_error(k);
        let (mut rot, mut trans) = (0.0f64, 0.0f64);
        let mut poses = Vec::new();
        for (h, truth) in hs.iter().zip(&s.views) {
            let pose = board_pose(k, h).unwrap();
            let (r, t) = pose_error(&pose, truth);
            (rot, trans) = (rot.max(r), trans.max(t));
            poses.push(pose);
        }
        let b: Vec<_> = poses.iter().map(|p| p.inverse()).collect();
        let (x, y) = hand_eye_ax_yb(&s.ee, &b).unwrap();
        let (xr, xt) = pose_error(&x, &s.x);
        let (yr, yt) = pose_error(&y, &s.y);
        eprintln!(
            "noise-free: reprojection {reprojection:.1e} px, K {k_error:.1e} px, poses \
             {rot:.1e} rad {trans:.1e} m, X {xr:.1e} rad {xt:.1e} m, Y {yr:.1e} rad {yt:.1e} m"
        );
        // Rounding only: the data are exact, each step a well-conditioned linear solve
        // (condition numbers up to ~1e4 after normalisation) on numbers of size ~1e3, so the
        // errors are ~1e-16 x 1e3 x 1e4 at most.
        assert!(reprojection < 1e-9, "{reprojection}");
        assert!(k_error < 1e-8, "{k_error}");
        assert!(rot < 1e-10 && trans < 1e-10, "{rot} {trans}");
        assert!(xr < 1e-10 && xt < 1e-10 && yr < 1e-10 && yt < 1e-10);
    }

    #[test]
    fn two_views_suffice_for_zhang_with_zero_skew() {
        let s = scene(41, 2);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let hs: Vec<_> = s
            .views
            .iter()
            .map(|p| homography(&board(), &pixels(K_TRUE, p, 0.0, &mut rng)).unwrap())
            .collect();
        let k = intrinsics_zhang(&hs).unwrap();
        eprintln!("two views: K {:.1e} px", max_k_error(k));
        assert!(max_k_error(k) < 1e-7, "{k:?}");
        assert!(intrinsics_zhang(&hs[..1]).is_none());
    }

    #[test]
    fn the_normalized_path_through_a_distorted_lens_recovers_the_poses() {
        // Pixels made through the lens, undistorted back, homography in normalized coordinates.
        let lens = Lens {
            fx: 600.0,
            fy: 610.0,
            cx: 320.0,
            cy: 240.0,
            distortion: [-0.2, 0.05, 1e-3, -5e-4, 0.0],
        };
        let s = scene(42, 10);
        let mut worst = (0.0f64, 0.0f64);
        for truth in &s.views {
            let normalized: Vec<[f64; 2]> = board()
                .into_iter()
                .map(|q| {
                    let c = truth * nalgebra::Point3::new(q[0], q[1], 0.0);
                    let [u, v] = lens.project_normalized(c.x / c.z, c.y / c.z);
                    lens.undistort(u, v).unwrap()
                })
                .collect();
            let h = homography(&board(), &normalized).unwrap();
            let (r, t) = pose_error(&board_pose_normalized(&h).unwrap(), truth);
            // Any scale and sign of H give the same pose.
            let (r2, t2) = pose_error(&board_pose_normalized(&(h * -3.0)).unwrap(), truth);
            worst = (worst.0.max(r).max(r2), worst.1.max(t).max(t2));
        }
        eprintln!("normalized path: {:.1e} rad {:.1e} m", worst.0, worst.1);
        // The undistortion's 1e-12 convergence bounds the normalized points' error; the
        // pose's sensitivity to them is ~ depth / board size ~ 3.
        assert!(worst.0 < 1e-10 && worst.1 < 1e-10, "{worst:?}");
    }

    #[test]
    fn eye_to_hand_is_the_same_problem_with_b_equal_to_p() {
        // Camera fixed in the world (Y = T_world_camera), board on the ee (X = T_ee_board).
        let mut rng = ChaCha8Rng::seed_from_u64(43);
        let x = random_pose(&mut rng, 0.1);
        let y = random_pose(&mut rng, 1.5);
        let views: Vec<_> = (0..20).map(|_| random_view(&mut rng, true)).collect();
        let ee: Vec<_> = views.iter().map(|p| y * p * x.inverse()).collect();
        let (xs, ys) = hand_eye_ax_yb(&ee, &views).unwrap();
        let (xr, xt) = pose_error(&xs, &x);
        let (yr, yt) = pose_error(&ys, &y);
        assert!(xr < 1e-10 && xt < 1e-10 && yr < 1e-10 && yt < 1e-10);
        let (a, b) = relative_motions_eye_to_hand(&ee, &views).unwrap();
        let xp = hand_eye_ax_xb(&a, &b).unwrap();
        let (r, t) = pose_error(&xp, &x);
        assert!(r < 1e-10 && t < 1e-10, "{r} {t}");
    }

    /// The errors of one noisy run (rad, m; K in px).
    struct NoisyRun {
        dk: [f64; 4],
        /// The worst board pose.
        pose: (f64, f64),
        /// X and Y from AX = YB.
        x: (f64, f64),
        y: (f64, f64),
        /// X from AX = XB.
        xp: (f64, f64),
        /// The two estimates of X, to compare with each other.
        estimates: [Isometry3<f64>; 2],
    }

    /// The eye-in-hand pipeline on 25 views with 0.3 px Gaussian pixel noise: homographies,
    /// Zhang's K, the board poses with Zhang's K (or with the true K, to see the hand-eye
    /// solutions' own noise), X and Y.
    fn noisy_run(seed: u64, true_k: bool) -> NoisyRun {
        let s = scene(seed, 30);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 1000);
        let hs: Vec<_> = s
            .views
            .iter()
            .map(|p| homography(&board(), &pixels(K_TRUE, p, 0.3, &mut rng)).unwrap())
            .collect();
        let k = intrinsics_zhang(&hs).unwrap();
        let k_used = if true_k { K_TRUE } else { k };
        let poses: Vec<_> = hs.iter().map(|h| board_pose(k_used, h).unwrap()).collect();
        let b: Vec<_> = poses.iter().map(|p| p.inverse()).collect();
        let (x, y) = hand_eye_ax_yb(&s.ee, &b).unwrap();
        let (a, bb) = relative_motions_eye_in_hand(&s.ee, &poses).unwrap();
        let xp = hand_eye_ax_xb(&a, &bb).unwrap();
        let mut pose = (0.0f64, 0.0f64);
        for (p, truth) in poses.iter().zip(&s.views) {
            let e = pose_error(p, truth);
            pose = (pose.0.max(e.0), pose.1.max(e.1));
        }
        NoisyRun {
            dk: std::array::from_fn(|i| k[i] - K_TRUE[i]),
            pose,
            x: pose_error(&x, &s.x),
            y: pose_error(&y, &s.y),
            xp: pose_error(&xp, &s.x),
            estimates: [x, xp],
        }
    }

    fn describe(run: &NoisyRun) -> String {
        let d = |(r, t): (f64, f64)| format!("{:.3} deg {:.2} mm", r.to_degrees(), t * 1e3);
        format!(
            "dK {:.2?} px, worst pose {}, X {}, Y {}, X (AX=XB) {}",
            run.dk,
            d(run.pose),
            d(run.x),
            d(run.y),
            d(run.xp)
        )
    }

    #[test]
    fn noisy_views_give_starts_within_their_bounds() {
        for seed in 50..58 {
            let known = noisy_run(seed, true);
            let zhang = noisy_run(seed, false);
            eprintln!("seed {seed} true K:  {}", describe(&known));
            eprintln!("seed {seed} Zhang K: {}", describe(&zhang));
            // Zhang's linear estimate is not the maximum-likelihood one, and the focal length
            // is fixed only by the boards' perspective: measured up to 2 px over these seeds.
            assert!(zhang.dk.iter().all(|d| d.abs() < 3.0), "{:?}", zhang.dk);
            // Each board's tilt is seen only through perspective: a 20 cm board at 0.3-0.5 m
            // moves its corners by f (h/2)² / z² ~ 10-25 px per radian of tilt, so 0.3 px noise
            // leaves each view's rotation uncertain by ~0.3 deg (worst of 30 views 0.5-0.7
            // deg). Averaged over 30 views (/5.5) that is ~0.05-0.1 deg on X and Y, 0.18 deg
            // at worst over these seeds; the translations follow through the 0.3-0.5 m lever
            // (up to 0.7 mm).
            for (r, t) in [known.x, known.y, known.xp] {
                assert!(r.to_degrees() < 0.25 && t < 1e-3, "{r} {t}");
            }
            // With Zhang's K the focal-length error (up to 2 px, 0.3 %) scales every board
            // distance (0.3-0.5 m) alike: up to 1.7 mm more on the translations.
            for (r, t) in [zhang.x, zhang.y, zhang.xp] {
                assert!(r.to_degrees() < 0.25 && t < 2.5e-3, "{r} {t}");
            }
        }
    }

    #[test]
    fn degenerate_input_is_refused() {
        let mut rng = ChaCha8Rng::seed_from_u64(60);
        let plane = board();
        // Homography: 3 points, collinear points, repeated points, NaN, lengths.
        let view = random_view(&mut rng, true);
        let image = pixels(K_TRUE, &view, 0.0, &mut rng);
        assert!(homography(&plane[..3], &image[..3]).is_none());
        assert!(
            homography(&plane[..9], &image[..9]).is_none(),
            "one row: collinear"
        );
        let repeated = [plane[0], plane[0], plane[1], plane[10]];
        let repeated_image = [image[0], image[0], image[1], image[10]];
        assert!(homography(&repeated, &repeated_image).is_none());
        let mut nan = image.clone();
        nan[5][1] = f64::NAN;
        assert!(homography(&plane, &nan).is_none());
        assert!(homography(&plane, &image[..20]).is_none());
        let corners = [plane[0], plane[8], plane[45], plane[53]];
        let corners_image = [image[0], image[8], image[45], image[53]];
        assert!(
            homography(&corners, &corners_image).is_some(),
            "4 points in general position"
        );

        // Zhang: all boards parallel to the image plane, identical views, NaN.
        let parallel: Vec<_> = (0..10)
            .map(|_| {
                let p = random_view(&mut rng, false);
                homography(&plane, &pixels(K_TRUE, &p, 0.0, &mut rng)).unwrap()
            })
            .collect();
        assert!(intrinsics_zhang(&parallel).is_none());
        let h = homography(&plane, &image).unwrap();
        assert!(intrinsics_zhang(&[h, h, h]).is_none());
        let mut bad = h;
        bad[(0, 1)] = f64::NAN;
        assert!(intrinsics_zhang(&[h, bad, h]).is_none());
        assert!(intrinsics_zhang(&[]).is_none());

        // Board pose: zero matrix, NaN, bad K, board origin in the focal plane.
        assert!(board_pose(K_TRUE, &Matrix3::zeros()).is_none());
        assert!(board_pose(K_TRUE, &bad).is_none());
        assert!(board_pose([0.0, 600.0, 320.0, 240.0], &h).is_none());
        assert!(board_pose([f64::NAN, 600.0, 320.0, 240.0], &h).is_none());
        let edge = Matrix3::new(1.0, 0.0, 0.1, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        assert!(board_pose_normalized(&edge).is_none());

        // Hand-eye: rotations all about one axis, identical poses, too few, NaN, lengths.
        let s = scene(61, 10);
        let axis = nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.2, 0.9));
        let about_one_axis: Vec<_> = (0..10)
            .map(|i| {
                Isometry3::from_parts(
                    Translation3::new(0.1 * i as f64, 0.02 * (i * i) as f64, 0.3),
                    UnitQuaternion::from_axis_angle(&axis, 0.3 * i as f64),
                )
            })
            .collect();
        let b_one: Vec<_> = about_one_axis
            .iter()
            .map(|e| (s.y.inverse() * e * s.x).inverse())
            .collect();
        assert!(hand_eye_ax_yb(&about_one_axis, &b_one).is_none());
        let (a, b) = relative_motions_eye_in_hand(
            &about_one_axis,
            &b_one.iter().map(|p| p.inverse()).collect::<Vec<_>>(),
        )
        .unwrap();
        assert!(hand_eye_ax_xb(&a, &b).is_none());
        let same = vec![s.ee[0]; 5];
        let same_b = vec![s.views[0].inverse(); 5];
        assert!(hand_eye_ax_yb(&same, &same_b).is_none());
        let b_all: Vec<_> = s.views.iter().map(|p| p.inverse()).collect();
        assert!(hand_eye_ax_yb(&s.ee[..2], &b_all[..2]).is_none());
        assert!(hand_eye_ax_yb(&s.ee, &b_all[..9]).is_none());
        let mut nan_pose = s.ee.clone();
        nan_pose[3].translation.vector.x = f64::NAN;
        assert!(hand_eye_ax_yb(&nan_pose, &b_all).is_none());
        let (a, b) = relative_motions_eye_in_hand(&nan_pose, &s.views).unwrap();
        assert!(hand_eye_ax_xb(&a, &b).is_none());
        assert!(relative_motions_eye_in_hand(&s.ee[..1], &s.views[..1]).is_none());
        // The same data without the defects is accepted.
        assert!(hand_eye_ax_yb(&s.ee, &b_all).is_some());
    }

    #[test]
    fn ax_yb_and_ax_xb_agree_on_the_same_eye_in_hand_data() {
        // Noise-free: both recover X. Noisy board poses (from 0.3 px): they agree to the
        // noise level.
        let s = scene(70, 25);
        let b: Vec<_> = s.views.iter().map(|p| p.inverse()).collect();
        let (x, _) = hand_eye_ax_yb(&s.ee, &b).unwrap();
        let (a, bb) = relative_motions_eye_in_hand(&s.ee, &s.views).unwrap();
        let xp = hand_eye_ax_xb(&a, &bb).unwrap();
        let (r, t) = pose_error(&x, &xp);
        assert!(r < 1e-10 && t < 1e-10, "{r} {t}");
        let run = noisy_run(71, true);
        let (x, xp) = (run.x, run.xp);
        let (r, t) = pose_error(&run.estimates[0], &run.estimates[1]);
        eprintln!(
            "AX=YB vs AX=XB (noisy): X errors {:.3} / {:.3} deg, {:.2} / {:.2} mm; apart \
             {:.3} deg {:.2} mm",
            x.0.to_degrees(),
            xp.0.to_degrees(),
            x.1 * 1e3,
            xp.1 * 1e3,
            r.to_degrees(),
            t * 1e3
        );
        // Each is within 0.1 deg and 1 mm of the truth (the noisy test), so within twice that
        // of each other.
        assert!(r.to_degrees() < 0.2 && t < 2e-3, "{r} {t}");
    }
}
