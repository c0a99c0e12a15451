//! The HTML report read as a person would: real bars, readable and distinct tick labels, every
//! kind of error the data has (and none it has not), and an assessed calibration that says so.

use kinecal::observe::Weights;
use kinecal::workflow::{self, Request, Selection, Validation};
use kinecal::{apps::simulate, model::examples, Robot};
use kinecal_report::html_report;

/// The README's GE A4 session: 30 noisy poses of a changed arm, 20 % held out.
fn session() -> (Robot, kinecal::Dataset) {
    let nominal = examples::ge_a4();
    let mut truth = nominal.clone();
    for (name, delta) in [
        ("p1", 0.05),
        ("p14", -0.02),
        ("joint2.offset", -0.5),
        ("joint4.slope", 0.02),
    ] {
        let id = kinecal::parse_param_list(name, &nominal).unwrap()[0];
        let q = nominal.param_quantity(id);
        truth.set(id, truth.get(id) + nominal.units.to_si(q, delta));
    }
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 7), false);
    simulate::add_noise(&mut data, 0.0005 * 0.0254, 0.005f64.to_radians(), 7);
    (nominal, data)
}

fn report(nominal: &Robot, data: kinecal::Dataset, list: &str, validation: Validation) -> String {
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::parse(list, None, nominal).unwrap();
    req.weights = Weights {
        length: 0.0005 * 0.0254,
        angle: 0.005f64.to_radians(),
    };
    req.validation = validation;
    html_report(&workflow::run(&req, &mut ()).unwrap().report).unwrap()
}

/// The part of the page under the heading with `id`, up to the next heading.
fn section<'a>(html: &'a str, id: &str) -> &'a str {
    let start = html
        .find(&format!("id=\"{id}\""))
        .unwrap_or_else(|| panic!("no section {id}"));
    let rest = &html[start..];
    let end = rest[1..].find("<h2").map_or(rest.len(), |e| e + 1);
    &rest[..end]
}

/// The texts drawn in the SVGs of a section (tick labels, titles, legends).
fn svg_texts(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = s;
    while let Some(i) = rest.find("<text") {
        rest = &rest[i..];
        let open = rest.find('>').unwrap();
        let close = rest.find("</text>").unwrap();
        out.push(rest[open + 1..close].trim().to_string());
        rest = &rest[close..];
    }
    out
}

/// The tick labels among the texts: those that read as numbers.
fn numbers(texts: &[String]) -> Vec<String> {
    texts
        .iter()
        .filter(|t| t.parse::<f64>().is_ok())
        .cloned()
        .collect()
}

#[test]
fn charts_read_as_a_person_reads_them() {
    let (nominal, data) = session();
    let html = report(
        &nominal,
        data,
        "p1,p2,p8,p14,offsets,slopes",
        Validation::Holdout {
            fraction: 0.2,
            seed: 1,
        },
    );
    // The histogram is bars (filled rectangles), counted in whole observations.
    let hist = section(&html, "histogram");
    let bars = hist.matches("<rect").count();
    assert!(bars >= 4, "{bars} rectangles");
    let labels = numbers(&svg_texts(hist));
    let counts: Vec<f64> = labels
        .iter()
        .map(|l| l.parse::<f64>().unwrap())
        .filter(|v| *v >= 1.0)
        .collect();
    assert!(!counts.is_empty());
    assert!(
        counts.iter().all(|c| c.fract() == 0.0),
        "fractional counts: {labels:?}"
    );
    // Parameter changes: distinct tick labels, no exponent, parameters named on the axis.
    let changes = section(&html, "changes");
    let texts = svg_texts(changes);
    for name in ["p1", "p14", "p32", "p38"] {
        assert!(
            texts.iter().any(|t| t == name),
            "{name} not on an axis: {texts:?}"
        );
    }
    // Each chart's tick labels are distinct (per SVG).
    for svg in changes.split("<svg").skip(1) {
        let ticks = numbers(&svg_texts(svg));
        let mut seen = ticks.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), ticks.len(), "repeated ticks: {ticks:?}");
        assert!(ticks.iter().all(|t| !t.contains('e')), "{ticks:?}");
    }
    // The spectrum's logarithmic axis: powers of ten, short, no rounding noise.
    let spectrum = section(&html, "spectrum");
    for t in svg_texts(spectrum)
        .iter()
        .filter(|t| t.starts_with("1e") || t.starts_with("0.0"))
    {
        assert!(t.len() <= 6, "long tick label `{t}`");
        assert!(!t.contains("999"), "rounding noise in `{t}`");
    }
    // Errors before and after on log axes, so that both can be read.
    let residuals = section(&html, "residuals");
    assert!(residuals.contains("log scale"), "linear error axis");
    // Tables in plain decimals: no 8.042730e-2 notation for ordinary magnitudes.
    let summary = section(&html, "summary");
    assert!(!summary.contains("e-"), "{summary}");
    assert!(summary.contains("0.08050"), "{summary}");
    // Validation: a table per kind of error (positions and attitudes here).
    let validation = section(&html, "validation");
    assert!(
        validation.contains("Position error (in)") && validation.contains("Attitude error (deg)")
    );
}

#[test]
fn tracker_free_data_shows_its_own_errors_and_an_assessed_calibration_says_so() {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/no-tracker/a4_table.toml"),
    )
    .unwrap();
    let robot = kinecal::model::robot_file::parse_robot_toml(&text, "a4_table.toml").unwrap();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/no-tracker");
    let read = |f: &str, parse: fn(&str, &str, &Robot) -> kinecal::Result<kinecal::Dataset>| {
        parse(&std::fs::read_to_string(dir.join(f)).unwrap(), f, &robot).unwrap()
    };
    let data = read("ballbar.csv", kinecal::files::parse_distances)
        .merge(read("contacts.csv", kinecal::files::parse_contacts));
    let mut req = Request::new(robot.clone(), data.clone());
    req.validation = Validation::Holdout {
        fraction: 0.3,
        seed: 1,
    };
    let out = workflow::run(&req, &mut ()).unwrap();
    let html = html_report(&out.report).unwrap();
    let validation = section(&html, "validation");
    assert!(validation.contains("Distance error (in)"), "{validation}");
    assert!(validation.contains("Contact error (in)"), "{validation}");
    assert!(!validation.contains("Position error"), "{validation}");
    for id in ["summary", "validation"] {
        let part = section(&html, id);
        assert!(
            !part.contains("0.000000"),
            "zeros shown for what was not measured: {part}"
        );
    }
    // The same calibration, assessed as a given robot: no iterations, no solver.
    let assessed = workflow::assess(
        &robot,
        &out.calibration.calibrated,
        &data,
        Weights::default(),
        Default::default(),
        &[],
    )
    .unwrap();
    let html = html_report(&assessed.report).unwrap();
    assert!(
        html.contains("a given calibration, assessed on these data (not solved here)"),
        "{}",
        &html[..800]
    );
    assert!(!html.contains("after 0 iterations"));
}

/// A robot in metres and radians: its page shows millimetres and degrees, every number
/// converted and labelled so; asked for, its own units.
#[test]
fn a_metre_radian_calibration_is_shown_in_millimetres_and_degrees() {
    let (mut nominal, data) = session();
    nominal.units = kinecal::Units {
        length: kinecal::LengthUnit::M,
        angle: kinecal::AngleUnit::Rad,
    };
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::parse("p1,p2,p8,p14,offsets,slopes", None, &nominal).unwrap();
    req.validation = Validation::Holdout {
        fraction: 0.2,
        seed: 1,
    };
    let rep = workflow::run(&req, &mut ()).unwrap().report;
    assert_eq!(rep.length_unit.as_str(), "m");
    let html = html_report(&rep).unwrap();
    let summary = section(&html, "summary");
    assert!(
        summary.contains("RMS position error (mm)") && summary.contains("RMS attitude error (deg)"),
        "{summary}"
    );
    let mm = kinecal_report::number::num(rep.rms_position_after * 1000.0);
    let deg = kinecal_report::number::num(rep.rms_orientation_after.unwrap().to_degrees());
    assert!(
        summary.contains(&format!("<td>{mm}</td>")),
        "{mm}: {summary}"
    );
    assert!(
        summary.contains(&format!("<td>{deg}</td>")),
        "{deg}: {summary}"
    );
    let validation = section(&html, "validation");
    assert!(
        validation.contains("Position error (mm)") && validation.contains("Attitude error (deg)")
    );
    // Parameters: lengths in mm, angles in deg, slopes in deg/unit; the change and sigma too.
    let changes = section(&html, "changes");
    for unit in ["mm", "deg", "deg/unit"] {
        assert!(
            changes.contains(&format!("<td class=\"l\">{unit}</td>")),
            "{unit}: {changes}"
        );
        assert!(
            changes.contains(&format!("change ({unit})")),
            "{unit} chart"
        );
    }
    let p1 = rep.parameters.iter().find(|p| p.id == "p1").unwrap();
    let row = changes
        .lines()
        .find(|l| l.starts_with("<tr><td class=\"l\">p1<"))
        .unwrap();
    assert!(
        row.contains(&kinecal_report::number::signed(p1.change * 1000.0, 4))
            && row.contains(&kinecal_report::number::num(p1.sigma.unwrap() * 1000.0)),
        "{row}"
    );
    // No number labelled in the robot's units is left.
    for stale in ["(m)", "(rad)", " m</", " rad<", "rad/unit", ">m<", ">rad<"] {
        assert!(!html.contains(stale), "`{stale}` on the page");
    }
    // The verdict speaks millimetres too.
    assert!(section(&html, "verdict").contains(" mm"));
    // Its own units when asked for.
    let own = kinecal_report::html_report_in(&rep, "m-rad".parse().unwrap()).unwrap();
    assert!(section(&own, "summary").contains("RMS position error (m)"));
    assert!(section(&own, "summary").contains(&format!(
        "<td>{}</td>",
        kinecal_report::number::num(rep.rms_position_after)
    )));
}
