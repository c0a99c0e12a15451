//! Data printed in the thesis, shared by the test files.

/// Table 4.8: the initial guesses of p1, p3, p9, p10, p15, p21, p27, p33 in its five runs.
pub const TABLE_4_8_GUESSES: [[f64; 8]; 5] = [
    [14.08, 10.00, -0.40, 2.00, 0.80, 1.00, 3.00, 0.35],
    [14.08, 12.00, -0.60, 2.00, 0.40, 1.20, 4.00, 0.45],
    [17.08, 9.00, 0.10, 2.00, -0.20, 0.30, 2.80, 0.50],
    [17.08, 13.00, 0.60, 2.00, -0.40, 1.00, 2.50, 0.15],
    [14.08, 12.00, -0.60, 3.00, 0.40, 1.20, 4.00, 0.45],
];

/// The parameters Table 4.8 estimates.
pub const TABLE_4_8_PARAMS: &str = "p1,p3,p9,p10,p15,p21,p27,p33";
