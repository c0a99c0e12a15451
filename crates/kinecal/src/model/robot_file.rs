//! The robot file: TOML in the user's units.
//!
//! ```toml
//! name = "GE A4"
//! length_unit = "in"      # "m", "mm" or "in"
//! angle_unit = "deg"      # "deg" or "rad"
//! end_effector = "right"  # optional: a name for the end-effector frame in `site` columns
//! [[links]]               # n+1 of them
//! x = 15.08               # missing components are 0
//! beta = 180.0
//! [[joints]]              # n of them
//! kind = "revolute"       # or "prismatic"
//! offset = 90.0           # angle_unit (revolute) or length_unit (prismatic); default 0
//! slope = 7.2             # per transducer unit; default 1
//! min = -14.0             # optional reading range (both or neither)
//! max = -6.0
//! coupling = { joint = 2, factor = 1.0 }   # optional: q += factor * V2 (angle_unit per unit)
//! name = "elbow_joint"    # optional: files may head this joint's reading column so
//! parent = 1              # optional, a tree: the link starts after joint 1 (a number, 0 the
//!                         # global frame, or an earlier joint's name), not the previous joint
//! [[sites]]               # optional (a tree's other tool frames are sites)
//! name = "elbow"
//! joint = 2               # attached right after joint 2 (or the joint's name)
//! x = 0.0                 # y, z, alpha, beta, gamma as for links
//! [[planes]]              # optional: planes touched in contact measurements
//! name = "table"
//! normal = [0, 0, 1]      # any length; the global frame
//! offset = 0.25           # length_unit: signed distance of the plane from the origin along normal
//! [[sessions]]            # optional: a session of measurements with its own measurement frame
//! name = "C"              # the observations' `session`
//! x = 508.0               # the robot's global frame in the session's measurement frame:
//! gamma = 1.5             # x, y, z, alpha, beta, gamma as for links
//! [[cameras]]             # optional: a camera whose pixel observations calibrate the robot
//! name = "wrist"          # its parameters: wrist.x .. wrist.gamma, wrist.fx .. wrist.k3
//! mount = "ee"            # "ee" (eye-in-hand), "base" (fixed beside the robot) or a site
//! pose = [0, 0, 0, 0, 0, 0]   # camera frame in the mount frame: x, y, z, alpha, beta, gamma;
//!                         # OpenCV's camera frame: z along the optical axis, x right, y down
//! fx = 600.0              # pixels; fy, cx, cy too
//! distortion = [-0.2, 0.05, 0, 0, 0]   # k1, k2, p1, p2, k3 (OpenCV's plumb bob); default 0
//! width = 640             # image size, pixels
//! height = 480
//! [[boards]]              # optional: a calibration board the cameras see
//! name = "board"          # its parameters: board.x .. board.gamma
//! mount = "base"          # as for cameras
//! pose = [0, 0, 0, 0, 0, 0]
//! cols = 9                # points along the board's x; point k at ((k % cols) * spacing,
//! rows = 6                # (k / cols) * spacing, 0) in the board frame
//! spacing = 25.0          # length_unit
//! [tolerances]            # optional: expected deviations, the metric of minimum-change answers
//! length = 0.04           # length, angle (file units), slope (a fraction), any parameter
//! [priors]                # optional: a calibration's Gaussian prior on the changes (the same
//! angle = 0.02            # keys as [tolerances], and compliance); `--prior` overrides it
//! ```
//!
//! A mass model ([`crate::model::robot::Elastic`]) makes the robot elastic: its joints yield to the
//! gravity torques of its bodies. It is there when the file has `[[bodies]]` or `[gravity]`:
//!
//! ```toml
//! [gravity]               # optional
//! vector = [0, 0, -9.81]  # length_unit/s^2 in the global (base) frame; this is the default
//! iterations = 5          # optional: a fixed number of fixed-point iterations of the
//!                         # equilibrium; default: to convergence (1e-10 rad)
//! lumped_mass = 28.0      # optional, without [[bodies]]: a lumped model of that total mass
//!                         # (kg), one equal point mass halfway along each moving link
//!                         # (written back as [[bodies]])
//! [[bodies]]              # point masses
//! joint = 2               # carried by the frame right after joint 2 (as for sites)
//! mass = 7.8              # kg
//! com = [0.3, 0, 0.1]     # length_unit, centre of mass in that frame
//! [[joints]]
//! compliance = 2e-4       # angle_unit/(N length_unit): the joint turns by compliance * torque
//!                         # (at least 0: a negative one is refused)
//! lateral = 5e-5          # the same about the lateral axis (at least 0)
//! lateral_axis = [1, 0, 0]   # unit, perpendicular to the joint axis, in the joint's frame;
//!                            # default: the common normal with the parent axis (written back)
//! ```
//!
//! Writing goes through [`write_robot_toml`], which updates the numbers of an existing document
//! and keeps everything else in it (comments, layout, keys kinecal does not know).

use std::ops::Range;

use toml_edit::{DocumentMut, Item, Table, Value};

use crate::error::{Error, Location, Result};
use crate::model::camera::{Board, Camera, Mount};
use crate::model::params::LinkComponent;
use crate::model::robot::{
    Body, Coupling, Elastic, Joint, JointKind, Link, Plane, Robot, Session, Site,
};
use crate::units::number::Scale;
use crate::units::{AngleUnit, LengthUnit, Quantity, Units};

pub(crate) fn line_of(text: &str, span: Option<Range<usize>>) -> Option<usize> {
    span.map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1)
}

/// Reads typed values out of a parsed TOML document, with errors naming file, line and field.
pub(crate) struct Reader<'t> {
    pub(crate) text: &'t str,
    pub(crate) file: &'t str,
}

impl<'t> Reader<'t> {
    pub(crate) fn err(
        &self,
        span: Option<Range<usize>>,
        field: &str,
        message: impl Into<String>,
    ) -> Error {
        let mut at = Location::file(self.file).with_field(field);
        at.line = line_of(self.text, span);
        Error::input(at, message)
    }

    pub(crate) fn number(&self, table: &Table, key: &str, field: &str) -> Result<Option<f64>> {
        let Some(item) = table.get(key) else {
            return Ok(None);
        };
        let v = match item.as_value() {
            Some(Value::Float(f)) => *f.value(),
            Some(Value::Integer(i)) => *i.value() as f64,
            _ => return Err(self.err(item.span(), field, "expected a number")),
        };
        if !crate::units::plausible(v) {
            return Err(self.err(
                item.span(),
                field,
                format!("expected a finite number within +-1e9, found {v:e}"),
            ));
        }
        Ok(Some(v))
    }

    /// A joint named by number (1-based; 0 the global frame) or by its `name` among `joints`
    /// (the ones read so far).
    fn joint_number(&self, item: &Item, field: &str, joints: &[Joint], key: &str) -> Result<usize> {
        if let Some(name) = item.as_str() {
            return match joints.iter().position(|j| j.name.as_deref() == Some(name)) {
                Some(j) => Ok(j + 1),
                None => Err(self.err(
                    item.span(),
                    field,
                    format!(
                        "no joint named `{name}` before this one (named joints: {})",
                        joints
                            .iter()
                            .filter_map(|j| j.name.as_deref())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )),
            };
        }
        match item.as_integer() {
            Some(k) if k >= 0 => Ok(k as usize),
            _ => Err(self.err(
                item.span(),
                field,
                format!(
                    "expected `{key} = K` (a joint number, 0 the global frame) or a joint's name"
                ),
            )),
        }
    }

    pub(crate) fn string<'a>(
        &self,
        table: &'a Table,
        key: &str,
        field: &str,
    ) -> Result<Option<&'a str>> {
        let Some(item) = table.get(key) else {
            return Ok(None);
        };
        item.as_str()
            .map(Some)
            .ok_or_else(|| self.err(item.span(), field, "expected a string"))
    }

    pub(crate) fn check_keys(&self, table: &Table, allowed: &[&str], what: &str) -> Result<()> {
        for (key, item) in table.iter() {
            if !allowed.contains(&key) {
                return Err(self.err(
                    item.span().or(table.span()),
                    &format!("{what}.{key}"),
                    format!(
                        "unknown key `{key}` (expected one of: {})",
                        allowed.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The tables of `key`: an array of tables (`[[key]]`), or an inline array of inline tables
    /// (`key = [{ ... }, { ... }]`, as some TOML writers produce).
    pub(crate) fn tables<'a>(
        &self,
        root: &'a Table,
        key: &str,
    ) -> Result<Vec<std::borrow::Cow<'a, Table>>> {
        use std::borrow::Cow;
        match root.get(key) {
            None => Ok(Vec::new()),
            Some(Item::ArrayOfTables(a)) => Ok(a.iter().map(Cow::Borrowed).collect()),
            Some(Item::Value(Value::Array(arr))) => arr
                .iter()
                .map(|v| match v {
                    Value::InlineTable(t) => Ok(Cow::Owned(t.clone().into_table())),
                    other => Err(self.err(
                        other.span(),
                        key,
                        format!("expected tables in `{key}`, e.g. [[{key}]] sections"),
                    )),
                })
                .collect(),
            Some(other) => Err(self.err(
                other.span(),
                key,
                format!("expected an array of tables, written as [[{key}]] sections"),
            )),
        }
    }

    /// The table of `key` (`[key]` or an inline `key = { ... }`), if present.
    pub(crate) fn table<'a>(
        &self,
        root: &'a Table,
        key: &str,
    ) -> Result<Option<std::borrow::Cow<'a, Table>>> {
        use std::borrow::Cow;
        match root.get(key) {
            None => Ok(None),
            Some(Item::Table(t)) => Ok(Some(Cow::Borrowed(t))),
            Some(Item::Value(Value::InlineTable(t))) => {
                Ok(Some(Cow::Owned(t.clone().into_table())))
            }
            Some(other) => Err(self.err(
                other.span(),
                key,
                format!("expected a table, written as [{key}]"),
            )),
        }
    }

    /// A 3-vector `[a, b, c]` of numbers, if present.
    pub(crate) fn vec3(&self, table: &Table, key: &str, field: &str) -> Result<Option<[f64; 3]>> {
        self.numbers(table, key, field, "[0, 0, 1]")
    }

    /// An array of `N` finite numbers within +-1e9 (`example` shows one in errors).
    fn numbers<const N: usize>(
        &self,
        table: &Table,
        key: &str,
        field: &str,
        example: &str,
    ) -> Result<Option<[f64; N]>> {
        let Some(item) = table.get(key) else {
            return Ok(None);
        };
        let bad = || {
            self.err(
                item.span(),
                field,
                format!("expected an array of {N} finite numbers within +-1e9, e.g. {example}"),
            )
        };
        let arr = item.as_array().ok_or_else(bad)?;
        if arr.len() != N {
            return Err(bad());
        }
        let mut out = [0.0; N];
        for (k, v) in arr.iter().enumerate() {
            out[k] = match v {
                Value::Float(f) => *f.value(),
                Value::Integer(i) => *i.value() as f64,
                _ => return Err(bad()),
            };
            if !crate::units::plausible(out[k]) {
                return Err(bad());
            }
        }
        Ok(Some(out))
    }

    /// Parses the document, or says where it is not TOML.
    pub(crate) fn parse(&self) -> Result<toml_edit::Document<&'t str>> {
        toml_edit::Document::parse(self.text).map_err(|e| {
            let mut at = Location::file(self.file);
            at.line = line_of(self.text, e.span());
            // An XML file (a URDF, a xacro) where a robot file was expected: say so.
            let start = self.text.trim_start_matches('\u{feff}').trim_start();
            if start.starts_with('<') {
                let kind = if start.contains("xmlns:xacro") {
                    "a xacro file"
                } else if start.contains("<robot") {
                    "a URDF"
                } else {
                    "XML"
                };
                return Error::input(
                    Location::file(self.file),
                    format!(
                        "this is {kind}, not a kinecal robot file (TOML): import it first, \
                         `kinecal import urdf {} --out robot.toml`, and give robot.toml",
                        self.file
                    ),
                );
            }
            Error::input(at, format!("invalid TOML: {}", e.message().trim()))
        })
    }

    /// The `length_unit` and `angle_unit` of a document's root.
    pub(crate) fn units(&self, root: &Table) -> Result<Units> {
        let unit = |key: &str, expected: &str| -> Result<(&str, Option<Range<usize>>)> {
            let s = self.string(root, key, key)?.ok_or_else(|| {
                self.err(None, key, format!("missing `{key}` (expected {expected})"))
            })?;
            Ok((s, root.get(key).and_then(Item::span)))
        };
        let (ls, lspan) = unit("length_unit", "\"m\", \"mm\" or \"in\"")?;
        let length: LengthUnit = ls
            .parse()
            .map_err(|m: String| self.err(lspan, "length_unit", m))?;
        let (as_, aspan) = unit("angle_unit", "\"deg\" or \"rad\"")?;
        let angle: AngleUnit = as_
            .parse()
            .map_err(|m: String| self.err(aspan, "angle_unit", m))?;
        Ok(Units { length, angle })
    }

    /// A joint's optional `coupling = { joint = K, factor = F }` (F in the file's units per
    /// reading unit of joint K; default 1).
    pub(crate) fn coupling(
        &self,
        t: &Table,
        what: &str,
        kind: JointKind,
        units: &Units,
        (this, count): (usize, usize),
    ) -> Result<Option<Coupling>> {
        Ok(match t.get("coupling") {
            None => None,
            Some(item) => {
                let field = format!("{what}.coupling");
                let bad = || {
                    self.err(
                        item.span().or(t.span()),
                        &field,
                        "expected `coupling = { joint = K, factor = F }` (K the number of the other \
                         joint, F the joint units added per unit of its reading; default 1)",
                    )
                };
                let ct = item.as_table_like().ok_or_else(bad)?;
                for (key, _) in ct.iter() {
                    if key != "joint" && key != "factor" {
                        return Err(self.err(
                            item.span().or(t.span()),
                            &format!("{field}.{key}"),
                            format!("unknown key `{key}` (expected joint, factor)"),
                        ));
                    }
                }
                let joint = match ct.get("joint").and_then(Item::as_integer) {
                    Some(k) if k >= 1 => k as usize - 1,
                    _ => return Err(bad()),
                };
                if joint == this || joint >= count {
                    let span = ct.get("joint").and_then(Item::span).or(item.span());
                    return Err(self.err(
                        span,
                        &format!("{field}.joint"),
                        if joint == this {
                            format!("joint {} cannot be coupled to itself", this + 1)
                        } else {
                            format!(
                                "joint {}: there is no joint {} (the robot has joints 1..{count})",
                                this + 1,
                                joint + 1
                            )
                        },
                    ));
                }
                let factor = match ct.get("factor") {
                    None => 1.0,
                    Some(f) => match f.as_float().or_else(|| f.as_integer().map(|i| i as f64)) {
                        Some(v) if crate::units::plausible(v) => v,
                        _ => {
                            return Err(self.err(
                                f.span().or(item.span()),
                                &format!("{field}.factor"),
                                "expected a finite number",
                            ))
                        }
                    },
                };
                Some(Coupling {
                    joint,
                    factor: units.to_si(kind.slope(), factor),
                })
            }
        })
    }

    /// The mass model: `[gravity]`, `[[bodies]]` and the joints' compliances.
    fn elastic(&self, root: &Table, robot: &Robot) -> Result<Option<Elastic>> {
        let units = robot.units;
        let gravity = self.table(root, "gravity")?;
        let body_tables = self.tables(root, "bodies")?;
        let joint_tables = self.tables(root, "joints")?;
        let compliance_keys = ["compliance", "lateral", "lateral_axis"];
        if gravity.is_none() && body_tables.is_empty() {
            for (i, t) in joint_tables.iter().enumerate() {
                if let Some(key) = compliance_keys.iter().find(|k| t.contains_key(k)) {
                    return Err(self.err(
                        t.get(key).and_then(Item::span),
                        &format!("joints[{i}].{key}"),
                        "a compliance needs a mass model: add [[bodies]] (joint, mass, com) to \
                         the robot file",
                    ));
                }
            }
            return Ok(None);
        }
        let mut bodies = Vec::new();
        for (i, t) in body_tables.iter().enumerate() {
            let t: &Table = t;
            let what = format!("bodies[{i}]");
            self.check_keys(t, &["joint", "mass", "com"], &what)?;
            let joint_field = format!("{what}.joint");
            let joint = match t.get("joint").and_then(Item::as_integer) {
                Some(j) if j >= 1 && (j as usize) <= robot.dof() => j as usize,
                _ => {
                    return Err(self.err(
                        t.get("joint").and_then(Item::span).or(t.span()),
                        &joint_field,
                        format!(
                            "expected `joint = K`, the joint (1..{}) right after which the body \
                             is carried",
                            robot.dof()
                        ),
                    ))
                }
            };
            let mass_field = format!("{what}.mass");
            let mass = self
                .number(t, "mass", &mass_field)?
                .ok_or_else(|| self.err(t.span(), &mass_field, "missing `mass` (kg)"))?;
            if mass < 0.0 {
                return Err(self.err(
                    t.get("mass").and_then(Item::span),
                    &mass_field,
                    "a mass cannot be negative",
                ));
            }
            let com = self
                .vec3(t, "com", &format!("{what}.com"))?
                .unwrap_or([0.0; 3]);
            bodies.push(Body {
                joint,
                mass,
                com: nalgebra::Vector3::from(com) * units.length.metres(),
            });
        }
        let mut model = Elastic::new(robot, bodies);
        if let Some(g) = &gravity {
            self.check_keys(g, &["vector", "iterations", "lumped_mass"], "gravity")?;
            if let Some(total) = self.number(g, "lumped_mass", "gravity.lumped_mass")? {
                if !model.bodies.is_empty() || total <= 0.0 {
                    return Err(self.err(
                        g.get("lumped_mass").and_then(Item::span),
                        "gravity.lumped_mass",
                        "a lumped model is a positive total mass (kg) for a robot without \
                         [[bodies]]",
                    ));
                }
                model.bodies = Elastic::lumped(robot, total);
            }
            if let Some(v) = self.vec3(g, "vector", "gravity.vector")? {
                model.gravity = nalgebra::Vector3::from(v) * units.length.metres();
            }
            if let Some(item) = g.get("iterations") {
                match item.as_integer() {
                    Some(n) if (1..=1000).contains(&n) => model.iterations = Some(n as usize),
                    _ => {
                        return Err(self.err(
                            item.span(),
                            "gravity.iterations",
                            "expected a whole number of iterations in 1..1000 (leave it out to \
                             iterate to convergence)",
                        ))
                    }
                }
            }
        }
        for (i, t) in joint_tables.iter().enumerate() {
            let what = format!("joints[{i}]");
            let revolute = robot.joints[i].kind == JointKind::Revolute;
            if !revolute {
                if let Some(key) = compliance_keys.iter().find(|k| t.contains_key(k)) {
                    return Err(self.err(
                        t.get(key).and_then(Item::span),
                        &format!("{what}.{key}"),
                        "only revolute joints have compliances",
                    ));
                }
                continue;
            }
            let j = &mut model.joints[i];
            for (key, slot) in [
                ("compliance", &mut j.compliance),
                ("lateral", &mut j.lateral),
            ] {
                if let Some(v) = self.number(t, key, &format!("{what}.{key}"))? {
                    // A negative compliance turns the joint against the torque: the arm rises.
                    if v < 0.0 {
                        return Err(self.err(
                            t.get(key).and_then(Item::span),
                            &format!("{what}.{key}"),
                            format!(
                                "expected a compliance of at least 0 (0: rigid), found {v}: a \
                                 negative one turns the joint against gravity's torque"
                            ),
                        ));
                    }
                    *slot = units.to_si(Quantity::Compliance, v);
                }
            }
            let axis_field = format!("{what}.lateral_axis");
            if let Some(a) = self.vec3(t, "lateral_axis", &axis_field)? {
                let a = nalgebra::Vector3::from(a);
                if !(a.norm() > 1e-9 && a.z.abs() <= 1e-6 * a.norm()) {
                    return Err(self.err(
                        t.get("lateral_axis").and_then(Item::span),
                        &axis_field,
                        "the lateral axis must be a non-zero vector perpendicular to the joint \
                         axis (z component 0), in the joint's frame",
                    ));
                }
                j.lateral_axis = nalgebra::Vector3::new(a.x, a.y, 0.0).normalize();
            }
        }
        Ok(Some(model))
    }

    fn link(&self, t: &Table, what: &str, units: &Units, extra: &[&str]) -> Result<Link> {
        let mut allowed = vec!["x", "y", "z", "alpha", "beta", "gamma"];
        allowed.extend_from_slice(extra);
        self.check_keys(t, &allowed, what)?;
        let mut link = Link::default();
        for c in LinkComponent::ALL {
            let field = format!("{what}.{}", c.as_str());
            if let Some(v) = self.number(t, c.as_str(), &field)? {
                *link.get_mut(c) = units.to_si(c.quantity(), v);
            }
        }
        Ok(link)
    }
}

/// Parses a robot file. `file` names it in error messages.
pub fn parse_robot_toml(text: &str, file: &str) -> Result<Robot> {
    let r = Reader { text, file };
    let doc = r.parse()?;
    let root = doc.as_table();
    let name = r.string(root, "name", "name")?.unwrap_or("").to_string();
    let units = r.units(root)?;
    let links = r
        .tables(root, "links")?
        .iter()
        .enumerate()
        .map(|(i, t)| r.link(t, &format!("links[{i}]"), &units, &[]))
        .collect::<Result<Vec<_>>>()?;
    let joint_tables = r.tables(root, "joints")?;
    let mut joints = Vec::new();
    for (i, t) in joint_tables.iter().enumerate() {
        let joint = r.joint(t, i, joint_tables.len(), &joints, &units)?;
        joints.push(joint);
    }
    let end_effector = r
        .string(root, "end_effector", "end_effector")?
        .map(str::to_string);
    let sites = (r.tables(root, "sites")?.iter().enumerate())
        .map(|(i, t)| r.site(t, i, &joints, &units))
        .collect::<Result<Vec<_>>>()?;
    let planes = (r.tables(root, "planes")?.iter().enumerate())
        .map(|(i, t)| r.plane(t, i, &units))
        .collect::<Result<Vec<_>>>()?;
    let sessions = (r.tables(root, "sessions")?.iter().enumerate())
        .map(|(i, t)| r.session(t, i, &units))
        .collect::<Result<Vec<_>>>()?;
    let mount_of = (sites.as_slice(), end_effector.as_deref());
    let cameras = (r.tables(root, "cameras")?.iter().enumerate())
        .map(|(i, t)| r.camera(t, i, &units, mount_of))
        .collect::<Result<Vec<_>>>()?;
    let boards = (r.tables(root, "boards")?.iter().enumerate())
        .map(|(i, t)| r.board(t, i, &units, mount_of))
        .collect::<Result<Vec<_>>>()?;
    let mut robot = Robot {
        name,
        units,
        links,
        joints,
        sites,
        planes,
        sessions,
        tolerances: Default::default(),
        priors: Default::default(),
        elastic: None,
        end_effector,
        cameras,
        boards,
    };
    let invalid = |m| Error::input(Location::file(file), m);
    robot.validate().map_err(invalid)?;
    robot.elastic = r.elastic(root, &robot)?;
    robot.validate().map_err(invalid)?;
    r.tolerances(root, &mut robot)?;
    r.priors(root, &mut robot)?;
    Ok(robot)
}

impl Reader<'_> {
    /// Joint `i` (0-based) of `count`, after the `earlier` ones.
    fn joint(
        &self,
        t: &Table,
        i: usize,
        count: usize,
        earlier: &[Joint],
        units: &Units,
    ) -> Result<Joint> {
        let r = self;
        let what = format!("joints[{i}]");
        r.check_keys(
            t,
            &[
                "kind",
                "offset",
                "slope",
                "min",
                "max",
                "coupling",
                "compliance",
                "lateral",
                "lateral_axis",
                "name",
                "parent",
            ],
            &what,
        )?;
        let kind_field = format!("{what}.kind");
        let kind = match r.string(t, "kind", &kind_field)? {
            Some("revolute") => JointKind::Revolute,
            Some("prismatic") => JointKind::Prismatic,
            Some(other) => {
                return Err(r.err(
                    t.get("kind").and_then(Item::span),
                    &kind_field,
                    format!(
                        "unknown joint kind `{other}` (expected \"revolute\" or \"prismatic\")"
                    ),
                ))
            }
            None => {
                return Err(r.err(
                    t.span(),
                    &kind_field,
                    "missing `kind` (expected \"revolute\" or \"prismatic\")",
                ))
            }
        };
        let offset = r
            .number(t, "offset", &format!("{what}.offset"))?
            .unwrap_or(0.0);
        let slope = r
            .number(t, "slope", &format!("{what}.slope"))?
            .unwrap_or(1.0);
        Ok(Joint {
            kind,
            offset: units.to_si(kind.variable(), offset),
            slope: units.to_si(kind.slope(), slope),
            coupling: r.coupling(t, &what, kind, units, (i, count))?,
            range: r.range(t, &what)?,
            name: r
                .string(t, "name", &format!("{what}.name"))?
                .map(str::to_string),
            parent: r.parent(t, i, &what, earlier)?,
        })
    }

    /// A joint's range: `min` below `max`, both or neither.
    fn range(&self, t: &Table, what: &str) -> Result<Option<(f64, f64)>> {
        let min = self.number(t, "min", &format!("{what}.min"))?;
        let max = self.number(t, "max", &format!("{what}.max"))?;
        match (min, max) {
            (None, None) => Ok(None),
            (Some(a), Some(b)) if a < b => Ok(Some((a, b))),
            (Some(_), Some(_)) => Err(self.err(
                t.get("min").and_then(Item::span),
                &format!("{what}.min"),
                "min must be below max",
            )),
            _ => Err(self.err(t.span(), what, "give both `min` and `max`, or neither")),
        }
    }

    /// The joint joint `i` hangs off (`None`: the previous one, the serial default).
    fn parent(&self, t: &Table, i: usize, what: &str, earlier: &[Joint]) -> Result<Option<usize>> {
        let Some(item) = t.get("parent") else {
            return Ok(None);
        };
        let field = format!("{what}.parent");
        let p = self.joint_number(item, &field, earlier, "parent")?;
        if p > i {
            return Err(self.err(
                item.span(),
                &field,
                format!(
                    "joint {} cannot hang off joint {p}: a parent comes before its children (0, \
                     the global frame, to {i})",
                    i + 1
                ),
            ));
        }
        // The previous joint is the serial default: one way to say it.
        Ok((p != i).then_some(p))
    }

    /// The `name` a table must have.
    fn name(&self, t: &Table, what: &str) -> Result<String> {
        let field = format!("{what}.name");
        Ok(self
            .string(t, "name", &field)?
            .ok_or_else(|| self.err(t.span(), &field, "missing `name`"))?
            .to_string())
    }

    /// Site `i`: a frame on a joint.
    fn site(&self, t: &Table, i: usize, joints: &[Joint], units: &Units) -> Result<Site> {
        let what = format!("sites[{i}]");
        let frame = self.link(t, &what, units, &["name", "joint"])?;
        let name = self.name(t, &what)?;
        let joint_field = format!("{what}.joint");
        let joint =
            match t.get("joint") {
                Some(item) if item.is_str() => {
                    self.joint_number(item, &joint_field, joints, "joint")?
                }
                item => match item.and_then(Item::as_integer) {
                    Some(j) if j >= 1 => j as usize,
                    _ => return Err(self.err(
                        item.and_then(Item::span).or(t.span()),
                        &joint_field,
                        "expected `joint = K`, the number (1..n) or name of the joint the site \
                         follows",
                    )),
                },
            };
        Ok(Site { name, joint, frame })
    }

    /// Plane `i`: a normal and an offset in the global frame.
    fn plane(&self, t: &Table, i: usize, units: &Units) -> Result<Plane> {
        let what = format!("planes[{i}]");
        self.check_keys(t, &["name", "normal", "offset"], &what)?;
        let name = self.name(t, &what)?;
        let normal_field = format!("{what}.normal");
        let normal = self.vec3(t, "normal", &normal_field)?.ok_or_else(|| {
            self.err(
                t.span(),
                &normal_field,
                "missing `normal = [nx, ny, nz]` (the plane's normal in the global frame)",
            )
        })?;
        let offset_field = format!("{what}.offset");
        let offset = self.number(t, "offset", &offset_field)?.ok_or_else(|| {
            self.err(
                t.span(),
                &offset_field,
                "missing `offset` (the plane's signed distance from the global origin along its \
                 normal, in length_unit)",
            )
        })?;
        Plane::new(
            name,
            nalgebra::Vector3::from(normal),
            units.to_si(Quantity::Length, offset),
        )
        .ok_or_else(|| {
            self.err(
                t.get("normal").and_then(Item::span),
                &normal_field,
                "the normal must not be zero",
            )
        })
    }

    /// A camera's or board's `mount`: `base`, `ee` (or the end effector's name), or a site.
    fn mount(
        &self,
        t: &Table,
        what: &str,
        (sites, end_effector): (&[Site], Option<&str>),
    ) -> Result<Mount> {
        let field = format!("{what}.mount");
        let expected = || {
            let mut names = vec!["\"base\"".to_string(), "\"ee\"".to_string()];
            names.extend(end_effector.map(|e| format!("\"{e}\"")));
            names.extend(sites.iter().map(|s| format!("\"{}\"", s.name)));
            format!("expected `mount` = {}", names.join(", "))
        };
        let name = self.string(t, "mount", &field)?.ok_or_else(|| {
            self.err(t.span(), &field, format!("missing `mount`: {}", expected()))
        })?;
        match name {
            "base" => Ok(Mount::Base),
            "ee" => Ok(Mount::EndEffector),
            n if end_effector == Some(n) => Ok(Mount::EndEffector),
            n => match sites.iter().position(|s| s.name == n) {
                Some(i) => Ok(Mount::Site(i)),
                None => Err(self.err(
                    t.get("mount").and_then(Item::span),
                    &field,
                    format!("unknown mount `{n}`: {}", expected()),
                )),
            },
        }
    }

    /// A camera's or board's `pose = [x, y, z, alpha, beta, gamma]` in its mount frame (the
    /// file's units; zeros when left out).
    fn pose(&self, t: &Table, what: &str, units: &Units) -> Result<Link> {
        let field = format!("{what}.pose");
        let mut link = Link::default();
        if let Some(v) = self.numbers::<6>(t, "pose", &field, "[0, 0, 0.1, 0, 0, 0]")? {
            for (c, x) in LinkComponent::ALL.into_iter().zip(v) {
                *link.get_mut(c) = units.to_si(c.quantity(), x);
            }
        }
        Ok(link)
    }

    /// A whole number in `range`, or the error naming `field` and `expected`.
    fn whole(
        &self,
        t: &Table,
        key: &str,
        field: &str,
        range: std::ops::RangeInclusive<i64>,
        expected: &str,
    ) -> Result<u32> {
        match t.get(key).map(|i| (i.as_integer(), i.span())) {
            Some((Some(n), _)) if range.contains(&n) => Ok(n as u32),
            Some((_, span)) => Err(self.err(span, field, format!("expected {expected}"))),
            None => Err(self.err(t.span(), field, format!("missing `{key}`: {expected}"))),
        }
    }

    /// Camera `i`: its mount, pose and lens.
    fn camera(
        &self,
        t: &Table,
        i: usize,
        units: &Units,
        mounts: (&[Site], Option<&str>),
    ) -> Result<Camera> {
        let what = format!("cameras[{i}]");
        self.check_keys(
            t,
            &[
                "name",
                "mount",
                "pose",
                "fx",
                "fy",
                "cx",
                "cy",
                "distortion",
                "width",
                "height",
            ],
            &what,
        )?;
        let name = self.name(t, &what)?;
        let mount = self.mount(t, &what, mounts)?;
        let pose = self.pose(t, &what, units)?;
        let mut lens = [0.0; 4];
        for (slot, key) in lens.iter_mut().zip(["fx", "fy", "cx", "cy"]) {
            let field = format!("{what}.{key}");
            *slot = self
                .number(t, key, &field)?
                .ok_or_else(|| self.err(t.span(), &field, format!("missing `{key}` (pixels)")))?;
        }
        let distortion = self
            .numbers::<5>(
                t,
                "distortion",
                &format!("{what}.distortion"),
                "[k1, k2, p1, p2, k3] = [-0.2, 0.05, 0, 0, 0]",
            )?
            .unwrap_or([0.0; 5]);
        let size = "a whole number of pixels in 1..100000";
        let width = self.whole(t, "width", &format!("{what}.width"), 1..=100_000, size)?;
        let height = self.whole(t, "height", &format!("{what}.height"), 1..=100_000, size)?;
        let camera = Camera {
            name,
            mount,
            pose,
            fx: lens[0],
            fy: lens[1],
            cx: lens[2],
            cy: lens[3],
            distortion,
            width,
            height,
        };
        camera
            .validate()
            .map_err(|m| self.err(t.get("fx").and_then(Item::span), &format!("{what}.fx"), m))?;
        Ok(camera)
    }

    /// Board `i`: its mount, pose and grid.
    fn board(
        &self,
        t: &Table,
        i: usize,
        units: &Units,
        mounts: (&[Site], Option<&str>),
    ) -> Result<Board> {
        let what = format!("boards[{i}]");
        self.check_keys(
            t,
            &["name", "mount", "pose", "cols", "rows", "spacing"],
            &what,
        )?;
        let name = self.name(t, &what)?;
        let mount = self.mount(t, &what, mounts)?;
        let pose = self.pose(t, &what, units)?;
        let count = "a whole number of points in 2..1000";
        let cols = self.whole(t, "cols", &format!("{what}.cols"), 2..=1000, count)?;
        let rows = self.whole(t, "rows", &format!("{what}.rows"), 2..=1000, count)?;
        let field = format!("{what}.spacing");
        let spacing = match self.number(t, "spacing", &field)? {
            Some(v) if v > 0.0 => units.to_si(Quantity::Length, v),
            Some(_) => {
                return Err(self.err(
                    t.get("spacing").and_then(Item::span),
                    &field,
                    "the spacing must be a positive length (length_unit)",
                ))
            }
            None => {
                return Err(self.err(
                    t.span(),
                    &field,
                    "missing `spacing` (the distance between neighbouring points, length_unit)",
                ))
            }
        };
        Ok(Board {
            name,
            mount,
            pose,
            cols,
            rows,
            spacing,
        })
    }

    /// Session `i`: a name and the frame its instrument stood in.
    fn session(&self, t: &Table, i: usize, units: &Units) -> Result<Session> {
        let what = format!("sessions[{i}]");
        let frame = self.link(t, &what, units, &["name"])?;
        Ok(Session {
            name: self.name(t, &what)?,
            frame,
        })
    }

    /// `[tolerances]`: `length`, `angle`, `slope` and parameters' own, positive.
    fn tolerances(&self, root: &Table, robot: &mut Robot) -> Result<()> {
        let Some(t) = self.table(root, "tolerances")? else {
            return Ok(());
        };
        let units = robot.units;
        for (key, item) in t.iter() {
            let field = format!("tolerances.{key}");
            let Some(v) = self.number(&t, key, &field)? else {
                continue;
            };
            if v <= 0.0 {
                return Err(self.err(item.span(), &field, "a tolerance must be positive"));
            }
            match key {
                "length" => robot.tolerances.length = units.to_si(Quantity::Length, v),
                "angle" => robot.tolerances.angle = units.to_si(Quantity::Angle, v),
                "slope" => robot.tolerances.slope_fraction = v,
                name => {
                    let id = crate::model::param_list::parse_param(name, robot).map_err(|e| {
                        self.err(
                            item.span(),
                            &field,
                            format!("{e} (expected length, angle, slope or a parameter)"),
                        )
                    })?;
                    let si = units.to_si(robot.param_quantity(id), v);
                    robot.tolerances.overrides.push((id, si));
                }
            }
        }
        Ok(())
    }

    /// `[priors]`: the prior on the parameters' changes (standard deviations), keyed as
    /// `[tolerances]` is.
    fn priors(&self, root: &Table, robot: &mut Robot) -> Result<()> {
        let Some(t) = self.table(root, "priors")? else {
            return Ok(());
        };
        let mut prior = crate::model::robot::Prior::default();
        for (key, item) in t.iter() {
            let field = format!("priors.{key}");
            let Some(v) = self.number(&t, key, &field)? else {
                continue;
            };
            crate::model::prior::set_key(&mut prior, key, v, robot)
                .map_err(|m| self.err(item.span(), &field, m))?;
        }
        robot.priors = prior;
        Ok(())
    }
}

/// The scales of a robot file's kinds of numbers (see [`crate::units::number`]), in the file's
/// units: lengths (link, site and session positions, plane offsets, prismatic offsets), angles
/// (their attitudes, revolute offsets) and slopes (slopes and coupling factors). A plane's normal
/// is a unit vector (scale 1); a joint range is its own scale (its larger bound).
struct Scales {
    length: Scale,
    angle: Scale,
    slope: Scale,
    compliance: Scale,
    mass: Scale,
}

impl Scales {
    fn of(robot: &Robot) -> Scales {
        let units = robot.units;
        let mut s = Scales {
            length: Scale::default(),
            angle: Scale::default(),
            slope: Scale::default(),
            compliance: Scale::default(),
            mass: Scale::default(),
        };
        let frames = robot
            .links
            .iter()
            .chain(robot.sites.iter().map(|x| &x.frame))
            .chain(robot.sessions.iter().map(|x| &x.frame))
            .chain(robot.cameras.iter().map(|x| &x.pose))
            .chain(robot.boards.iter().map(|x| &x.pose));
        for l in frames {
            for c in LinkComponent::ALL {
                let q = c.quantity();
                s.of_mut(q).include(units.from_si(q, l.get(c)));
            }
        }
        for p in &robot.planes {
            s.length.include(units.from_si(Quantity::Length, p.offset));
        }
        if let Some(e) = &robot.elastic {
            for j in &e.joints {
                for v in [j.compliance, j.lateral] {
                    s.compliance.include(units.from_si(Quantity::Compliance, v));
                }
            }
            for b in &e.bodies {
                s.mass.include(b.mass);
                for v in b.com.iter() {
                    s.length.include(units.from_si(Quantity::Length, *v));
                }
            }
        }
        for j in &robot.joints {
            let q = j.kind.variable();
            s.of_mut(q).include(units.from_si(q, j.offset));
            s.slope.include(units.from_si(j.kind.slope(), j.slope));
            if let Some(c) = j.coupling {
                s.slope.include(units.from_si(j.kind.slope(), c.factor));
            }
        }
        s
    }

    fn of_mut(&mut self, q: Quantity) -> &mut Scale {
        match q {
            Quantity::Length => &mut self.length,
            Quantity::Angle => &mut self.angle,
            Quantity::LengthPerReading | Quantity::AnglePerReading => &mut self.slope,
            Quantity::Compliance => &mut self.compliance,
            Quantity::Mass | Quantity::Pixel | Quantity::Ratio => &mut self.mass,
        }
    }

    fn of_quantity(&self, q: Quantity) -> Scale {
        match q {
            Quantity::Length => self.length,
            Quantity::Angle => self.angle,
            Quantity::LengthPerReading | Quantity::AnglePerReading => self.slope,
            Quantity::Compliance => self.compliance,
            Quantity::Mass => self.mass,
            // A lens's numbers have their own scales (see `write_optics`).
            Quantity::Pixel | Quantity::Ratio => Scale(1.0),
        }
    }
}

/// A number as a TOML value, through [`crate::units::number::format_number`] (with `.0` added to
/// a whole number, so that it stays a float).
fn toml_number(v: f64) -> Value {
    let mut text = crate::units::number::format_number(v);
    if !text.contains(['.', 'e', 'n']) {
        text.push_str(".0");
    }
    text.parse().unwrap_or_else(|_| Value::from(v))
}

fn set_number(table: &mut Table, key: &str, v: f64, scale: Scale) {
    let mut new = toml_number(crate::units::tidy(v, scale));
    if let Some(old) = table.get(key).and_then(Item::as_value) {
        *new.decor_mut() = old.decor().clone();
    }
    table.insert(key, Item::Value(new));
}

fn set_string(table: &mut Table, key: &str, v: &str) {
    let mut new = Value::from(v);
    if let Some(old) = table.get(key).and_then(Item::as_value) {
        if old.as_str() == Some(v) {
            return;
        }
        *new.decor_mut() = old.decor().clone();
    }
    table.insert(key, Item::Value(new));
}

fn array_of_tables<'d>(
    root: &'d mut Table,
    key: &str,
    len: usize,
) -> &'d mut toml_edit::ArrayOfTables {
    if !matches!(root.get(key), Some(Item::ArrayOfTables(_))) {
        root.insert(key, Item::ArrayOfTables(Default::default()));
    }
    let arr = root
        .get_mut(key)
        .and_then(Item::as_array_of_tables_mut)
        .expect("just inserted");
    while arr.len() < len {
        arr.push(Table::new());
    }
    while arr.len() > len {
        arr.remove(arr.len() - 1);
    }
    arr
}

fn write_link(t: &mut Table, l: &Link, units: &Units, scales: &Scales) {
    for c in LinkComponent::ALL {
        let q = c.quantity();
        set_number(
            t,
            c.as_str(),
            units.from_si(q, l.get(c)),
            scales.of_quantity(q),
        );
    }
}

fn set_vec3(table: &mut Table, key: &str, v: &nalgebra::Vector3<f64>, scale: Scale) {
    let mut arr = toml_edit::Array::new();
    for k in 0..3 {
        arr.push(toml_number(crate::units::tidy(v[k], scale)));
    }
    let mut new = Value::Array(arr);
    if let Some(old) = table.get(key).and_then(Item::as_value) {
        *new.decor_mut() = old.decor().clone();
    }
    table.insert(key, Item::Value(new));
}

/// The mass model: `[gravity]`, `[[bodies]]`, and each revolute joint's compliances and lateral
/// axis (written out, so that the axis stays the one the compliances were estimated with).
fn write_elastic(root: &mut Table, robot: &Robot, scales: &Scales) {
    let Some(e) = &robot.elastic else {
        return;
    };
    let units = robot.units;
    let metres = units.length.metres();
    if !root.contains_key("gravity") {
        root.insert("gravity", Item::Table(Table::new()));
    }
    if let Some(g) = root.get_mut("gravity").and_then(Item::as_table_mut) {
        let v = e.gravity / metres;
        set_vec3(g, "vector", &v, Scale::of([v.x, v.y, v.z]));
        // A lumped model is written out as its bodies.
        g.remove("lumped_mass");
        match e.iterations {
            Some(n) => {
                g.insert("iterations", Item::Value(Value::from(n as i64)));
            }
            None => {
                g.remove("iterations");
            }
        }
    }
    let bodies = array_of_tables(root, "bodies", e.bodies.len());
    for (t, b) in bodies.iter_mut().zip(&e.bodies) {
        t.insert("joint", Item::Value(Value::from(b.joint as i64)));
        set_number(t, "mass", b.mass, scales.mass);
        set_vec3(t, "com", &(b.com / metres), scales.length);
    }
    let joints = root
        .get_mut("joints")
        .and_then(Item::as_array_of_tables_mut)
        .expect("joints written");
    for ((t, j), el) in joints.iter_mut().zip(&robot.joints).zip(&e.joints) {
        if j.kind != JointKind::Revolute {
            continue;
        }
        for (key, v) in [("compliance", el.compliance), ("lateral", el.lateral)] {
            set_number(
                t,
                key,
                units.from_si(Quantity::Compliance, v),
                scales.compliance,
            );
        }
        set_vec3(t, "lateral_axis", &el.lateral_axis, Scale(1.0));
    }
}

/// The name a `mount` key writes for `m`.
fn mount_name(robot: &Robot, m: Mount) -> &str {
    match m {
        Mount::Base => "base",
        Mount::EndEffector => robot.end_effector.as_deref().unwrap_or("ee"),
        Mount::Site(s) => &robot.sites[s].name,
    }
}

/// A pose as `[x, y, z, alpha, beta, gamma]` in the file's units.
fn set_pose(t: &mut Table, l: &Link, units: &Units, scales: &Scales) {
    let mut arr = toml_edit::Array::new();
    for c in LinkComponent::ALL {
        let q = c.quantity();
        arr.push(toml_number(crate::units::tidy(
            units.from_si(q, l.get(c)),
            scales.of_quantity(q),
        )));
    }
    let mut v = Value::Array(arr);
    if let Some(old) = t.get("pose").and_then(Item::as_value) {
        *v.decor_mut() = old.decor().clone();
    }
    t.insert("pose", Item::Value(v));
}

/// `[[cameras]]` and `[[boards]]`.
fn write_optics(root: &mut Table, robot: &Robot, scales: &Scales) {
    let units = robot.units;
    if !robot.cameras.is_empty() || root.contains_key("cameras") {
        let cameras = array_of_tables(root, "cameras", robot.cameras.len());
        for (t, c) in cameras.iter_mut().zip(&robot.cameras) {
            set_string(t, "name", &c.name);
            set_string(t, "mount", mount_name(robot, c.mount));
            set_pose(t, &c.pose, &units, scales);
            let pixels = Scale::of([c.fx, c.fy, c.cx, c.cy]);
            for (key, v) in [("fx", c.fx), ("fy", c.fy), ("cx", c.cx), ("cy", c.cy)] {
                set_number(t, key, v, pixels);
            }
            let mut arr = toml_edit::Array::new();
            for v in c.distortion {
                arr.push(toml_number(crate::units::tidy(v, Scale(1.0))));
            }
            let mut v = Value::Array(arr);
            if let Some(old) = t.get("distortion").and_then(Item::as_value) {
                *v.decor_mut() = old.decor().clone();
            }
            t.insert("distortion", Item::Value(v));
            t.insert("width", Item::Value(Value::from(c.width as i64)));
            t.insert("height", Item::Value(Value::from(c.height as i64)));
        }
    }
    if !robot.boards.is_empty() || root.contains_key("boards") {
        let boards = array_of_tables(root, "boards", robot.boards.len());
        for (t, b) in boards.iter_mut().zip(&robot.boards) {
            set_string(t, "name", &b.name);
            set_string(t, "mount", mount_name(robot, b.mount));
            set_pose(t, &b.pose, &units, scales);
            t.insert("cols", Item::Value(Value::from(b.cols as i64)));
            t.insert("rows", Item::Value(Value::from(b.rows as i64)));
            set_number(
                t,
                "spacing",
                units.from_si(Quantity::Length, b.spacing),
                scales.length,
            );
        }
    }
}

/// [`write_robot_toml`] after checking the model (every parameter finite and within +-1e9 in
/// the file's units): what kinecal writes, it can read back.
pub fn write_robot_toml_checked(robot: &Robot, original: Option<&str>) -> Result<String> {
    robot.validate().map_err(|m| {
        Error::Problem(format!(
            "the computed robot cannot be written: {m} (diverged, or a unit mix-up in the input?)"
        ))
    })?;
    // What the reader refuses is not written: a negative compliance (a fit the data left free).
    let negative: Vec<String> = robot
        .param_ids()
        .filter(|&id| {
            matches!(
                robot.param_kind(id),
                crate::model::params::ParamKind::Compliance { .. }
                    | crate::model::params::ParamKind::Lateral { .. }
            ) && robot.get(id) < 0.0
        })
        .map(|id| format!("{} = {}", robot.param_name(id), robot.get_user(id)))
        .collect();
    if !negative.is_empty() {
        return Err(Error::Problem(format!(
            "the computed robot cannot be written: negative compliances {} (a joint that turns \
             against gravity; a robot file holds none): hold them, or give them a prior \
             (--prior compliance=...)",
            negative.join(", ")
        )));
    }
    Ok(write_robot_toml(robot, original))
}

/// Writes `robot` as a robot file. With `original` (the text of the file the robot was read
/// from), only the model's numbers and names change: comments, layout and any other keys are
/// kept. Without it, a fresh file is written. Numbers are written as
/// [`crate::units::number`] says, each kind with the file's scale of it (see `Scales`): float
/// noise as 0, the rest to 15 significant digits when that is within 4 ulps
/// (`tidy`), in the shortest text that reads back the same.
pub fn write_robot_toml(robot: &Robot, original: Option<&str>) -> String {
    let mut doc: DocumentMut = original.and_then(|t| t.parse().ok()).unwrap_or_default();
    let units = robot.units;
    let scales = Scales::of(robot);
    let root = doc.as_table_mut();
    set_string(root, "name", &robot.name);
    set_string(root, "length_unit", units.length.as_str());
    set_string(root, "angle_unit", units.angle.as_str());
    let links = array_of_tables(root, "links", robot.links.len());
    for (t, l) in links.iter_mut().zip(&robot.links) {
        write_link(t, l, &units, &scales);
    }
    match &robot.end_effector {
        Some(name) => set_string(root, "end_effector", name),
        None => {
            root.remove("end_effector");
        }
    }
    let names: Vec<Option<String>> = robot.joints.iter().map(|j| j.name.clone()).collect();
    let joints = array_of_tables(root, "joints", robot.joints.len());
    for (t, j) in joints.iter_mut().zip(&robot.joints) {
        match &j.name {
            Some(name) => set_string(t, "name", name),
            None => {
                t.remove("name");
            }
        }
        match j.parent {
            Some(p) => {
                // By name when the file said it so and the parent has one.
                let by_name = t.get("parent").is_some_and(Item::is_str);
                let mut v = match names.get(p.wrapping_sub(1)).cloned().flatten() {
                    Some(name) if by_name => Value::from(name),
                    _ => Value::from(p as i64),
                };
                if let Some(old) = t.get("parent").and_then(Item::as_value) {
                    *v.decor_mut() = old.decor().clone();
                }
                t.insert("parent", Item::Value(v));
            }
            None => {
                t.remove("parent");
            }
        }
        set_string(t, "kind", j.kind.as_str());
        let (variable, slope) = (j.kind.variable(), j.kind.slope());
        set_number(
            t,
            "offset",
            units.from_si(variable, j.offset),
            scales.of_quantity(variable),
        );
        set_number(t, "slope", units.from_si(slope, j.slope), scales.slope);
        if let Some((a, b)) = j.range {
            let own = Scale::of([a, b]);
            set_number(t, "min", a, own);
            set_number(t, "max", b, own);
        }
        match j.coupling {
            Some(c) => {
                let factor = crate::units::tidy(units.from_si(slope, c.factor), scales.slope);
                match t.get_mut("coupling").and_then(Item::as_table_like_mut) {
                    Some(ct) => {
                        let mut joint = Value::from(c.joint as i64 + 1);
                        if let Some(old) = ct.get("joint").and_then(Item::as_value) {
                            *joint.decor_mut() = old.decor().clone();
                        }
                        ct.insert("joint", Item::Value(joint));
                        let mut f = toml_number(factor);
                        if let Some(old) = ct.get("factor").and_then(Item::as_value) {
                            *f.decor_mut() = old.decor().clone();
                        }
                        ct.insert("factor", Item::Value(f));
                    }
                    None => {
                        let mut it = toml_edit::InlineTable::new();
                        it.insert("joint", Value::from(c.joint as i64 + 1));
                        it.insert("factor", toml_number(factor));
                        t.insert("coupling", Item::Value(Value::InlineTable(it)));
                    }
                }
            }
            None => {
                t.remove("coupling");
            }
        }
    }
    write_elastic(root, robot, &scales);
    if !robot.sites.is_empty() || root.contains_key("sites") {
        let sites = array_of_tables(root, "sites", robot.sites.len());
        for (t, s) in sites.iter_mut().zip(&robot.sites) {
            set_string(t, "name", &s.name);
            let by_name = t.get("joint").is_some_and(Item::is_str);
            let mut joint = match names.get(s.joint.wrapping_sub(1)).cloned().flatten() {
                Some(name) if by_name => Value::from(name),
                _ => Value::from(s.joint as i64),
            };
            if let Some(old) = t.get("joint").and_then(Item::as_value) {
                *joint.decor_mut() = old.decor().clone();
            }
            t.insert("joint", Item::Value(joint));
            write_link(t, &s.frame, &units, &scales);
        }
    }
    if !robot.planes.is_empty() || root.contains_key("planes") {
        let planes = array_of_tables(root, "planes", robot.planes.len());
        for (t, p) in planes.iter_mut().zip(&robot.planes) {
            set_string(t, "name", &p.name);
            let n = p.normal();
            let mut arr = toml_edit::Array::new();
            for k in 0..3 {
                arr.push(toml_number(crate::units::tidy(n[k], Scale(1.0))));
            }
            let mut v = Value::Array(arr);
            if let Some(old) = t.get("normal").and_then(Item::as_value) {
                *v.decor_mut() = old.decor().clone();
            }
            t.insert("normal", Item::Value(v));
            set_number(
                t,
                "offset",
                units.from_si(Quantity::Length, p.offset),
                scales.length,
            );
        }
    }
    if !robot.sessions.is_empty() || root.contains_key("sessions") {
        let sessions = array_of_tables(root, "sessions", robot.sessions.len());
        for (t, s) in sessions.iter_mut().zip(&robot.sessions) {
            set_string(t, "name", &s.name);
            write_link(t, &s.frame, &units, &scales);
        }
    }
    write_optics(root, robot, &scales);
    doc.to_string()
}
