//! Lengths and angles in display units: the pages and summaries a person reads show millimetres
//! and degrees for a robot whose files are in metres and radians (see
//! [`DisplayUnits::for_robot`]), or the units chosen (a spec's `display_units`). Only what is
//! shown is converted: the documents written for programs (the JSON report, robot files) keep
//! the robot file's units.
//!
//! A renderer converts a report once ([`calibration`], [`prediction`]) and takes every unit it
//! prints from the same [`Convert`] ([`Convert::l`], [`Convert::a`]), never from the report's
//! `length_unit` and `angle_unit`, which still name the robot file's units.

use kinecal::units::{AngleUnit, LengthUnit};
pub use kinecal::units::{DisplayChoice, DisplayLength, DisplayUnits};

use kinecal::predict::{AccuracyMap, BoundSummary, GrowthReport, PredictionReport};
use kinecal::report::{CalibrationReport, DatasetAccuracy, ErrorStats, MetricStats};

/// The conversion of numbers in a robot file's units to display units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Convert {
    /// The units shown.
    pub units: DisplayUnits,
    /// The robot file's length unit.
    pub robot_length: LengthUnit,
    /// The robot file's angle unit.
    pub robot_angle: AngleUnit,
}

impl Convert {
    /// From a robot's `length` and `angle` units to `units`.
    pub fn new(units: DisplayUnits, length: LengthUnit, angle: AngleUnit) -> Convert {
        Convert {
            units,
            robot_length: length,
            robot_angle: angle,
        }
    }

    /// The conversion of `rep`'s numbers to `units`.
    pub fn of(rep: &CalibrationReport, units: DisplayUnits) -> Convert {
        Convert::new(units, rep.length_unit, rep.angle_unit)
    }

    /// A length, shown.
    pub fn length(&self, v: f64) -> f64 {
        v * self.units.length_factor(self.robot_length)
    }

    /// An angle, shown.
    pub fn angle(&self, v: f64) -> f64 {
        v * self.units.angle_factor(self.robot_angle)
    }

    /// The label of lengths shown: `mm`.
    pub fn l(&self) -> &'static str {
        self.units.length.as_str()
    }

    /// The label of angles shown: `deg`.
    pub fn a(&self) -> &'static str {
        self.units.angle.as_str()
    }

    /// A number labelled `unit` in the robot file's units (a parameter's `m`, `rad/unit`,
    /// `rad/(N m)`): the factor that shows it and the label it is shown with. A compliance
    /// keeps its torque in the robot's `N m`; a unit that is not a length's or an angle's (`kg`)
    /// is kept.
    pub fn unit(&self, unit: &str) -> (f64, String) {
        let (l, a) = (self.robot_length.as_str(), self.robot_angle.as_str());
        let (lf, af) = (self.length(1.0), self.angle(1.0));
        if unit == l {
            (lf, self.l().to_string())
        } else if unit == a {
            (af, self.a().to_string())
        } else if unit == format!("{l}/unit") {
            (lf, format!("{}/unit", self.l()))
        } else if unit == format!("{a}/unit") {
            (af, format!("{}/unit", self.a()))
        } else if unit == format!("{a}/(N {l})") {
            (af, format!("{}/(N {l})", self.a()))
        } else {
            (1.0, unit.to_string())
        }
    }
}

fn stats(s: &mut ErrorStats, c: &Convert) {
    for v in [
        &mut s.rms_position,
        &mut s.mean_position,
        &mut s.p95_position,
        &mut s.max_position,
    ] {
        *v = c.length(*v);
    }
    for v in [
        &mut s.rms_orientation,
        &mut s.mean_orientation,
        &mut s.p95_orientation,
        &mut s.max_orientation,
    ]
    .into_iter()
    .flatten()
    {
        *v = c.angle(*v);
    }
    for m in &mut s.other {
        metric(m, c);
    }
}

fn metric(m: &mut MetricStats, c: &Convert) {
    // A camera's reprojection error is in pixels whatever the length unit.
    if m.metric == "pixel" {
        return;
    }
    for v in [&mut m.rms, &mut m.mean, &mut m.p95, &mut m.max] {
        *v = c.length(*v);
    }
}

fn dataset(d: &mut DatasetAccuracy, c: &Convert) {
    stats(&mut d.before, c);
    if let Some(s) = &mut d.start {
        stats(s, c);
    }
    stats(&mut d.after, c);
}

/// The unit shared by the parameters `ids` of `rep`, if they share one (a combination of
/// them then has that unit, its coefficients plain numbers).
fn shared_unit<'a>(
    rep: &CalibrationReport,
    ids: impl IntoIterator<Item = &'a str>,
) -> Option<String> {
    let mut unit: Option<&str> = None;
    for id in ids {
        let u = rep.parameters.iter().find(|p| p.id == id)?.unit.as_str();
        match unit {
            None => unit = Some(u),
            Some(v) if v == u => {}
            Some(_) => return None,
        }
    }
    unit.map(str::to_string)
}

/// The parameter ids (`p12`) an expression such as `p3 - (p9 + p15)` names.
fn ids_in(expression: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let b = expression.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i] == b'p' && (i == 0 || !b[i - 1].is_ascii_alphanumeric());
        if starts {
            let end = (i + 1..b.len())
                .find(|&k| !b[k].is_ascii_digit())
                .unwrap_or(b.len());
            let tail_ok = end == b.len() || !(b[end].is_ascii_alphanumeric() || b[end] == b'.');
            if end > i + 1 && tail_ok {
                out.push(&expression[i..end]);
            }
            i = end.max(i + 1);
        } else {
            i += 1;
        }
    }
    out
}

/// The unit of a combination (`p3 - p9 - p15`) of a report converted by [`calibration`]: its
/// members' when they share one; else its value is in the robot file's units, named so.
pub fn combination_unit(shown: &CalibrationReport, expression: &str) -> String {
    shared_unit(shown, ids_in(expression)).unwrap_or_else(|| {
        format!(
            "the robot file's units, {} and {}",
            shown.length_unit, shown.angle_unit
        )
    })
}

/// `rep` with every length and angle it shows converted by `c`: errors, parameters (relabelled:
/// `mm`, `deg/unit`), sigmas, changes, combinations of parameters of one unit (see
/// [`combination_unit`]), the prediction, the per-observation errors, outliers, the mass
/// model. Its `length_unit` and `angle_unit` still name the robot file's: labels come from `c`.
pub fn calibration(rep: &CalibrationReport, c: &Convert) -> CalibrationReport {
    let mut r = rep.clone();
    r.weight_length = c.length(r.weight_length);
    r.weight_angle = c.angle(r.weight_angle);
    fit_errors(&mut r, c);
    parameters(&mut r, rep, c);
    accuracy(&mut r, c);
    observation_errors(&mut r, c);
    if let Some(e) = &mut r.elastic {
        elastic(e, rep, c);
    }
    r.prediction = r.prediction.as_ref().map(|p| prediction(p, c));
    r
}

/// The errors of the fit: before, at the solver's start, after, and the full fit's before
/// pruning.
fn fit_errors(r: &mut CalibrationReport, c: &Convert) {
    if let Some(s) = &mut r.start {
        s.rms_position = c.length(s.rms_position);
        s.max_position = c.length(s.max_position);
        s.rms_orientation = s.rms_orientation.map(|v| c.angle(v));
        s.max_orientation = s.max_orientation.map(|v| c.angle(v));
    }
    for v in [
        &mut r.rms_position_before,
        &mut r.rms_position_after,
        &mut r.max_position_before,
        &mut r.max_position_after,
    ] {
        *v = c.length(*v);
    }
    for v in [
        &mut r.rms_orientation_before,
        &mut r.rms_orientation_after,
        &mut r.max_orientation_before,
        &mut r.max_orientation_after,
    ]
    .into_iter()
    .flatten()
    {
        *v = c.angle(*v);
    }
    if let Some(p) = &mut r.pruning {
        p.full_rms_position_after = c.length(p.full_rms_position_after);
        p.full_rms_orientation_after = p.full_rms_orientation_after.map(|v| c.angle(v));
    }
}

/// The parameters (relabelled, with their sigmas and changes), and the combinations and
/// redundant groups of parameters of one unit (`rep`, the report as it came, knows their
/// units).
fn parameters(r: &mut CalibrationReport, rep: &CalibrationReport, c: &Convert) {
    for p in &mut r.parameters {
        let (f, label) = c.unit(&p.unit);
        p.unit = label;
        p.initial *= f;
        p.estimated *= f;
        p.change *= f;
        p.sigma = p.sigma.map(|v| v * f);
        p.prior_sigma = p.prior_sigma.map(|v| v * f);
    }
    for k in &mut r.combinations {
        if let Some(u) = shared_unit(rep, k.terms.iter().map(|t| t.id.as_str())) {
            let f = c.unit(&u).0;
            k.initial *= f;
            k.value *= f;
            k.sigma *= f;
        }
    }
    if let Some(s) = &mut r.spectrum {
        for g in &mut s.identical_groups {
            if let Some(u) = shared_unit(rep, ids_in(&g.expression)) {
                g.value *= c.unit(&u).0;
            }
        }
    }
}

/// The accuracy on the identification and validation data, of the model choice's candidates
/// and of the cross-validation's folds, and a far start's placement.
fn accuracy(r: &mut CalibrationReport, c: &Convert) {
    dataset(&mut r.identification, c);
    if let Some(v) = &mut r.validation {
        dataset(v, c);
    }
    for m in &mut r.model_choice {
        m.mean = c.length(m.mean);
        m.standard_error = c.length(m.standard_error);
    }
    if let Some(cv) = &mut r.cross_validation {
        for f in &mut cv.folds {
            metric(&mut f.errors, c);
        }
        metric(&mut cv.overall, c);
        cv.mean_low = c.length(cv.mean_low);
        cv.mean_high = c.length(cv.mean_high);
    }
    if let Some(p) = &mut r.start_placement {
        p.rms_before = c.length(p.rms_before);
        p.rms_after = c.length(p.rms_after);
    }
}

/// The outliers' errors, and the errors of each observation with their histogram's width.
fn observation_errors(r: &mut CalibrationReport, c: &Convert) {
    for o in &mut r.outliers {
        o.position_error = c.length(o.position_error);
        o.orientation_error = o.orientation_error.map(|v| c.angle(v));
    }
    if let Some(e) = &mut r.observation_errors {
        // Pixels stay pixels (a camera's data alone: the metric is `pixel`).
        let pixels = e.metric == "pixel";
        let length = |v: f64| if pixels { v } else { c.length(v) };
        for v in e.before.iter_mut().chain(e.after.iter_mut()) {
            *v = length(*v);
        }
        for list in [&mut e.attitude_before, &mut e.attitude_after]
            .into_iter()
            .flatten()
        {
            for v in list.iter_mut().flatten() {
                *v = c.angle(*v);
            }
        }
        e.histogram_width = length(e.histogram_width);
    }
}

/// The mass model: gravity, the largest deflection, the joints' compliances and stiffnesses
/// (a stiffness per angle shown: `N m/deg`).
fn elastic(e: &mut kinecal::report::ElasticReport, rep: &CalibrationReport, c: &Convert) {
    e.gravity = c.length(e.gravity);
    e.largest_deflection = c.angle(e.largest_deflection);
    let (f, _) = c.unit(&format!("{}/(N {})", rep.angle_unit, rep.length_unit));
    for j in &mut e.joints {
        j.compliance *= f;
        j.compliance_sigma = j.compliance_sigma.map(|v| v * f);
        j.stiffness = j.stiffness.map(|v| v / f);
        j.stiffness_sigma = j.stiffness_sigma.map(|v| v / f);
        j.stiffness_unit = j
            .stiffness_unit
            .replace(&format!("/{}", rep.angle_unit), &format!("/{}", c.a()));
    }
}

fn growth(g: &mut GrowthReport, value: f64, c: &Convert) {
    // `s0` in its quantity's unit; `c` that unit per length unit of distance.
    g.s0 *= value;
    g.s0_constant *= value;
    g.c *= value / c.length(1.0);
    g.distance_median = c.length(g.distance_median);
    g.distance_max = c.length(g.distance_max);
}

fn bound(b: &mut BoundSummary, f: impl Fn(f64) -> f64) {
    b.median = f(b.median);
    b.p95 = f(b.p95);
    b.median_measured = f(b.median_measured);
}

/// Replaces each number after `= ` or `+-` in a slice's title (a height, a slab's half
/// width, in the robot's length unit) by its value shown, with its unit.
fn slice_title(title: &str, c: &Convert) -> String {
    let mut out = String::new();
    let mut rest = title;
    loop {
        let next = ["= ", "+-"]
            .iter()
            .filter_map(|m| rest.find(m).map(|i| (i, m.len())))
            .min();
        let Some((i, n)) = next else {
            out += rest;
            return out;
        };
        out += &rest[..i + n];
        rest = &rest[i + n..];
        let end = rest
            .find(|ch: char| !(ch.is_ascii_digit() || ch == '.' || ch == '-'))
            .unwrap_or(rest.len());
        if let Ok(v) = rest[..end].parse::<f64>() {
            out += &format!("{} {}", crate::number::num(c.length(v)), c.l());
            rest = &rest[end..];
        }
    }
}

fn map(m: &mut AccuracyMap, c: &Convert) {
    m.unit = c.l().to_string();
    m.scale = m.scale.map(|v| c.length(v));
    for s in &mut m.slices {
        s.title = slice_title(&s.title, c);
        s.extent = s.extent.map(|v| c.length(v));
        for v in s.values.iter_mut().flatten() {
            *v = c.length(*v);
        }
        for p in &mut s.measured {
            *p = p.map(|v| c.length(v));
        }
    }
    for j in &mut m.joints {
        for v in j.median.iter_mut().chain(j.p95.iter_mut()).flatten() {
            *v = c.length(*v);
        }
    }
}

/// `p` with the lengths and angles its page shows converted by `c` (its covariance, levers
/// and measured readings, which no page shows, as they are).
pub fn prediction(p: &PredictionReport, c: &Convert) -> PredictionReport {
    let mut p = p.clone();
    growth(&mut p.position, c.length(1.0), c);
    if let Some(a) = &mut p.attitude {
        growth(a, c.angle(1.0), c);
    }
    bound(&mut p.position_summary, |v| c.length(v));
    if let Some(a) = &mut p.attitude_summary {
        bound(a, |v| c.angle(v));
    }
    if let Some(m) = &mut p.map {
        map(m, c);
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metre_radian() -> Convert {
        Convert::new(
            DisplayUnits::for_robot(LengthUnit::M, AngleUnit::Rad),
            LengthUnit::M,
            AngleUnit::Rad,
        )
    }

    #[test]
    fn a_metre_radian_robot_is_shown_in_millimetres_and_degrees() {
        let c = metre_radian();
        assert_eq!((c.l(), c.a()), ("mm", "deg"));
        assert!((c.length(0.0004394) - 0.4394).abs() < 1e-12);
        assert!((c.angle(0.000005222) - 0.000_299_2).abs() < 1e-7);
        let (f, label) = c.unit("rad/unit");
        assert_eq!(label, "deg/unit");
        assert!((f - 57.29577951308232).abs() < 1e-9);
        assert_eq!(c.unit("m").1, "mm");
        assert_eq!(c.unit("rad/(N m)").1, "deg/(N m)");
        let (f, label) = c.unit("kg");
        assert!((f - 1.0).abs() < 1e-15 && label == "kg");
        // A robot in inches and degrees is shown as it is.
        let inch = Convert::new(
            DisplayUnits::for_robot(LengthUnit::In, AngleUnit::Deg),
            LengthUnit::In,
            AngleUnit::Deg,
        );
        assert_eq!((inch.l(), inch.a()), ("in", "deg"));
        assert!((inch.length(15.08) - 15.08).abs() < 1e-12);
        let (f, label) = inch.unit("deg/unit");
        assert!((f - 1.0).abs() < 1e-15 && label == "deg/unit");
        // Micrometres when asked.
        let um = Convert::new("um-deg".parse().unwrap(), LengthUnit::Mm, AngleUnit::Deg);
        assert_eq!(um.l(), "um");
        assert!((um.length(0.25) - 250.0).abs() < 1e-9);
    }

    #[test]
    fn slice_titles_and_expressions() {
        let c = metre_radian();
        assert_eq!(
            slice_title("horizontal slice at z = 0.512 (+-0.050)", &c),
            "horizontal slice at z = 512.0 mm (+-50.00 mm)"
        );
        assert_eq!(
            slice_title(
                "vertical slice through joint 1's axis at 45 deg (measured within +-0.050)",
                &c
            ),
            "vertical slice through joint 1's axis at 45 deg (measured within +-50.00 mm)"
        );
        assert_eq!(
            ids_in("p3 - (p9 + p15 + 0.5 p21) + pa + p2.x"),
            ["p3", "p9", "p15", "p21"]
        );
    }
}
