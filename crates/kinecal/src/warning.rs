//! Things a user should know about a result, with the quantities in them.
//!
//! The library words each warning neutrally ([`std::fmt::Display`]); front ends may word them
//! their own way (the command line adds which option to use).

use serde::{Deserialize, Serialize};

/// A warning, with its quantities.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "warning", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Warning {
    /// Parameters left out of the default set because no observation sees their frame (or its
    /// attitude).
    Unseen {
        /// Their names.
        parameters: Vec<String>,
    },
    /// Estimated parameters that no residual feels: they keep their initial values.
    Unfelt {
        /// Their names.
        parameters: Vec<String>,
    },
    /// The rank from the tolerance differs from the largest gap in the spectrum.
    UnclearRank {
        /// Rank from the tolerance.
        rank: usize,
        /// The tolerance.
        rcond: f64,
        /// The rank the largest gap suggests.
        gap_rank: usize,
        /// The gap's ratio.
        gap_ratio: f64,
    },
    /// The gap at the rank is small.
    SmallGap {
        /// The rank.
        rank: usize,
        /// The gap's ratio.
        gap_ratio: f64,
    },
    /// Full rank, but the smallest scaled singular value is tiny.
    BarelyDetermined {
        /// Smallest over largest scaled singular value.
        ratio: f64,
    },
    /// A link or site frame at beta = +-90 deg: its alpha and gamma cannot be told apart.
    EulerSingular {
        /// The frame (`link3`, `site.NAME`).
        frame: String,
    },
    /// Two determined estimates are strongly correlated.
    Correlated {
        /// First parameter (id).
        a: String,
        /// Second parameter (id).
        b: String,
        /// Correlation coefficient.
        rho: f64,
    },
    /// The solver stopped at its iteration cap.
    NotConverged {
        /// Iterations run.
        iterations: usize,
    },
    /// The gravity equilibrium of an elastic robot did not converge at some postures (its
    /// compliances are too large for the fixed-point iteration, or the robot would buckle).
    EquilibriumNotConverged {
        /// Postures where it did not.
        postures: usize,
        /// Postures in all.
        of: usize,
    },
    /// The method stalled where Levenberg-Marquardt still reduces the objective.
    Stalled {
        /// The method (`gn`, `sd`, `svd`).
        method: String,
    },
    /// The uncertainty could not be computed.
    NoUncertainty {
        /// Why.
        reason: String,
    },
    /// A prediction was asked for and cannot be made.
    NoPrediction {
        /// Why.
        reason: String,
    },
    /// The data has no degrees of freedom left: standard deviations are not estimated.
    ExactFit,
    /// The measured spread (positions about their centroid, or distances) is far from what the
    /// nominal robot predicts for the same postures: most likely the data is in another length
    /// unit than the robot file.
    ScaleMismatch {
        /// `position` or `distance`.
        metric: String,
        /// Measured over predicted spread.
        ratio: f64,
        /// The robot file's length unit.
        unit: String,
        /// The unit the data is likely in, when the ratio matches one.
        likely: Option<String>,
    },
    /// Readings outside a joint's range (by more than 5 % of its width).
    ReadingsOutOfRange {
        /// Joint number (1-based).
        joint: usize,
        /// How many postures.
        count: usize,
        /// The first few postures' labels.
        postures: Vec<String>,
        /// The range's lower end (reading units).
        min: f64,
        /// The range's upper end (reading units).
        max: f64,
    },
    /// Joint readings taken directly as angles look like the other angle unit.
    AngleUnitMismatch {
        /// The joints (1-based).
        joints: Vec<usize>,
        /// The robot file's angle unit.
        file_unit: String,
        /// What the readings look like.
        looks_like: String,
    },
    /// The measured attitudes disagree with the nominal robot's far beyond any calibration
    /// error: the angle of the relative rotation between two poses of a target (the same in
    /// every measurement frame and for every tool frame) differs from the model's by a median
    /// of `median_deg`. `likely`: the angle unit in which the file's attitudes would agree
    /// (else another Euler convention, or not the same target).
    AttitudeMismatch {
        /// The median disagreement (deg).
        median_deg: f64,
        /// The unit the attitudes look like they are in, if one fits.
        likely: Option<String>,
        /// The unit they were read in.
        read_as: String,
    },
    /// After calibration, the measured attitudes still disagree with the model by an RMS of
    /// `rms_deg`: no geometry fits them, so they are most likely not ZYX Euler angles of the
    /// measured frame (another convention, another frame).
    AttitudesUnfit {
        /// The RMS attitude error after calibration (deg).
        rms_deg: f64,
    },
    /// After calibration the measured positions still disagree with the model by more than 2 %
    /// of the robot's reach (RMS): the fit stopped at a local minimum far from any calibration
    /// of this robot, or the data do not belong to it.
    PositionsUnfit {
        /// The RMS position error after calibration (file units).
        rms: f64,
        /// The robot's reach (file units).
        reach: f64,
        /// The length unit.
        unit: String,
    },
    /// The fit from the given start ended with the positions unfit (beyond 2 % of the reach), so
    /// it was tried again from other starts (the closed-form placement of the nominal robot and
    /// of the local minimum, a few well-spread starts), the best by objective kept.
    Restarted {
        /// Every start tried, the given one first.
        starts: Vec<StartTried>,
        /// The start kept (one of `starts`).
        kept: String,
    },
    /// The solver stopped where the scaled Jacobian determines fewer directions than at its start
    /// ([`crate::solve::estimation::Termination::RankLost`]).
    RankLost {
        /// The rank at the start.
        start_rank: usize,
        /// The rank at the end.
        rank: usize,
    },
    /// The postures fall into groups, each fitted far better by a rigid placement of its own
    /// than by one for all: measurements from several placements of the instrument pooled in
    /// one file without a `session` column.
    PooledPlacements {
        /// The groups, as line ranges of the measurement file (`lines 2-41`), in order.
        blocks: Vec<String>,
        /// The RMS position error with one placement for all, the robot held (file units).
        rms_pooled: f64,
        /// The RMS position error with a placement per group, the robot held (file units).
        rms_per_block: f64,
        /// The length unit.
        unit: String,
    },
    /// The calibrated robot does worse on the held-out data than the robot it started from:
    /// the mean error of `metric` grew from `before` to `after` (file units).
    WorseOnValidation {
        /// `position`, `distance`, ...
        metric: String,
        /// The held-out mean before calibration.
        before: f64,
        /// After.
        after: f64,
        /// The unit of both.
        unit: String,
    },
    /// The residuals are far from the stated standard deviations: the variance factor (the
    /// weighted objective per degree of freedom) is above 100 or below 0.01, the sigmas off by
    /// more than 10 times.
    SigmasOff {
        /// The variance factor.
        variance_factor: f64,
    },
    /// Rows with standard deviations of their own (an instrument's) had residuals far beyond
    /// them: each was weighted by `max(sigma, m)`, with the model error `m` of its quantity
    /// estimated from the residuals
    /// ([`crate::solve::estimation::weighting`]).
    ModelErrorFloor {
        /// The own rows' residuals' RMS over their stated sigmas, before the floor.
        scale: f64,
        /// The model error bounding the length rows' sigmas from below, in mm (0: none, or no
        /// such rows).
        length_mm: f64,
        /// The model error bounding the angle rows' sigmas from below, in degrees (0: none, or
        /// no such rows).
        angle_deg: f64,
        /// The length and angle rows with a standard deviation of their own.
        rows: usize,
        /// Those of them stating one above their quantity's model error, which they keep (the
        /// others are weighted alike, by the model error).
        above: usize,
    },
    /// The fit's residuals were far beyond the stated sigmas, so the identifiable set was
    /// chosen again at the residuals' noise (the noise-level rule at `scale` times the stated
    /// sigmas) and fitted again without the parameters that left.
    ChosenAtResidualNoise {
        /// The residuals' RMS over the stated sigmas (square root of the first fit's variance
        /// factor).
        scale: f64,
        /// The parameters left out then.
        left_out: Vec<String>,
    },
    /// Parameters the start's closed-form placement set from the data, estimated although the
    /// data determine them more loosely than the noise-level rule of the identifiable set
    /// allows (see [`crate::identifiability::AnalysisOptions::placed`]).
    PlacedLoose {
        /// Their names, each with its standard deviation and its change (mm or deg).
        parameters: Vec<String>,
    },
    /// Estimated lengths moved by more than the robot's reach.
    ChangeBeyondReach {
        /// Their names.
        parameters: Vec<String>,
        /// The reach (file units).
        reach: f64,
        /// The length unit.
        unit: String,
    },
    /// Fitted joint compliances below zero: joints that would turn against gravity's torque, a
    /// robot that rises (what the data gave where the compliances are poorly determined).
    NegativeCompliance {
        /// Their names and values (file units).
        parameters: Vec<String>,
    },
    /// Fitted slopes far from the robot file's (by more than [`SLOPE_CHANGE`] of them):
    /// readings in another unit or scale, or a coupling the model lacks.
    SlopeFarOff {
        /// Their names and values (file units).
        parameters: Vec<String>,
    },
    /// The gravity deflection of a joint reaches beyond [`DEFLECTION_LIMIT`]: no industrial
    /// joint yields that far under its own arm's weight.
    LargeDeflection {
        /// The largest deflection (deg).
        degrees: f64,
    },
    /// Parameters determined worse than the robot's stated accuracy (their standard deviation
    /// above their tolerance) and moved by many of their standard deviations: the data leaves
    /// them to the start's pull and the noise's.
    LooseAndMoved {
        /// Their names, with the change in standard deviations.
        parameters: Vec<String>,
    },
    /// Targets of the validation data that no identification row measures: their frames were
    /// never identified, so their errors are the nominal frames' (not the calibration's).
    ValidationTargetsUnseen {
        /// Their names.
        targets: Vec<String>,
    },
    /// URDF export: a joint's slope cannot be expressed in URDF.
    UrdfSlope {
        /// Joint number (1-based).
        joint: usize,
        /// URDF joint name.
        name: String,
        /// The slope (rad or m per unit).
        slope: f64,
    },
    /// URDF export: a coupled joint's URDF value is the sum of two readings.
    UrdfCoupled {
        /// Joint number (1-based).
        joint: usize,
        /// URDF joint name.
        name: String,
        /// The other joint (1-based).
        other: usize,
    },
    /// URDF export: the tip hung off the last movable joint; a fixed joint and a link that is
    /// the calibrated tool frame were added.
    UrdfToolAdded {
        /// The new link's name.
        link: String,
    },
}

/// How much a warning matters, for ranking them: errors first, then cautions, then notes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    /// The result is most likely wrong ([`Warning::implausible`]).
    Error,
    /// The result may not be what it seems: look before using it.
    Caution,
    /// Worth knowing; the result stands.
    Note,
}

impl Severity {
    /// `error`, `caution` or `note`.
    pub fn as_str(self) -> &'static str {
        match self {
            Severity::Error => "error",
            Severity::Caution => "caution",
            Severity::Note => "note",
        }
    }
}

impl Warning {
    /// How much the warning matters.
    pub fn severity(&self) -> Severity {
        if self.implausible() {
            return Severity::Error;
        }
        match self {
            Warning::Unseen { .. }
            | Warning::Unfelt { .. }
            | Warning::Correlated { .. }
            | Warning::EulerSingular { .. }
            | Warning::ExactFit
            | Warning::BarelyDetermined { .. }
            | Warning::UrdfSlope { .. }
            | Warning::UrdfCoupled { .. }
            | Warning::UrdfToolAdded { .. }
            | Warning::ModelErrorFloor { .. }
            | Warning::Restarted { .. } => Severity::Note,
            _ => Severity::Caution,
        }
    }

    /// True for the checks of the data's units at the door: lengths or angles that look like
    /// another unit than the robot file's, readings outside the joints' ranges (often the other
    /// angle unit), attitudes that disagree with the robot beyond any calibration error.
    pub fn names_units(&self) -> bool {
        matches!(
            self,
            Warning::ScaleMismatch { .. }
                | Warning::ReadingsOutOfRange { .. }
                | Warning::AngleUnitMismatch { .. }
                | Warning::AttitudeMismatch { .. }
        )
    }

    /// True for the checks of the fit's end that say the model could not fit the data: RMS
    /// residuals beyond any calibration error, lengths moved beyond the robot's size.
    pub fn fit_far_off(&self) -> bool {
        matches!(
            self,
            Warning::AttitudesUnfit { .. }
                | Warning::PositionsUnfit { .. }
                | Warning::ChangeBeyondReach { .. }
        )
    }

    /// True for the warnings that say the result is most likely wrong, whatever the fit's
    /// figures (units mixed up, readings impossible for the robot, lengths moved beyond its
    /// size): a strict caller stops there.
    pub fn implausible(&self) -> bool {
        self.names_units()
            || self.fit_far_off()
            || matches!(
                self,
                Warning::WorseOnValidation { .. } | Warning::PooledPlacements { .. }
            )
    }
}

/// One start of a fit that was tried again ([`Warning::Restarted`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct StartTried {
    /// Which start (`given`, `nominal placed`, `local minimum placed`, `spread 1`, ...).
    pub start: String,
    /// The objective the fit from it reached.
    pub objective: f64,
    /// Its RMS position error (file units).
    pub rms_position: f64,
    /// Whether its solver converged.
    pub converged: bool,
}

/// The change of a slope from the robot file's, as a fraction of it, beyond which
/// [`Warning::SlopeFarOff`] says so: transducers are made to 0.1 %, a calibration moves them by
/// a few tenths of a percent, a unit or gear-ratio slip by tens of percent or more.
pub const SLOPE_CHANGE: f64 = 0.1;

/// The gravity deflection (rad) beyond which [`Warning::LargeDeflection`] says so: a tenth of a
/// radian (5.7 deg); an industrial arm's joints yield by hundredths of a degree.
pub const DEFLECTION_LIMIT: f64 = 0.1;

/// How many standard deviations a loosely determined parameter may move before
/// [`Warning::LooseAndMoved`] names it.
pub const LOOSE_MOVE_SIGMAS: f64 = 5.0;

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::ScaleMismatch {
                metric,
                ratio,
                unit,
                likely,
            } => write!(
                f,
                "the measured {metric}s spread {} times as widely as the nominal robot predicts \
                 for the same postures: {}the data is read in the robot file's length unit \
                 ({unit}): state the file's unit when it is another",
                if *ratio >= 10.0 {
                    format!("{ratio:.0}")
                } else if *ratio >= 0.01 {
                    format!("{ratio:.3}")
                } else {
                    format!("{ratio:.2e}")
                },
                match likely {
                    Some(l) => format!("are they in {l}? "),
                    None => String::new(),
                }
            ),
            Warning::ReadingsOutOfRange {
                joint,
                count,
                postures,
                min,
                max,
            } => write!(
                f,
                "joint {joint}: {count} posture(s) read outside its range [{min}, {max}] \
                 (postures {}{}): wrong column, wrong unit, or a wrong range in the robot file",
                postures.join(", "),
                if *count > postures.len() { ", ..." } else { "" }
            ),
            Warning::AttitudeMismatch {
                median_deg,
                likely,
                read_as,
            } => match likely {
                Some(u) => write!(
                    f,
                    "the measured attitudes look like {u}, not {read_as}: relative rotations \
                     between poses differ from the nominal robot's by a median {median_deg:.1} \
                     deg as read, and agree in {u}; state the file's angle unit"
                ),
                None => write!(
                    f,
                    "the measured attitudes disagree with the nominal robot's by a median \
                     {median_deg:.1} deg (relative rotations between poses, independent of the \
                     measurement and tool frames): another Euler convention than ZYX, another \
                     target, or not this robot? Use positions only if the attitudes cannot be \
                     read as ZYX Euler angles"
                ),
            },
            Warning::AttitudesUnfit { rms_deg } => write!(
                f,
                "after calibration the measured attitudes still disagree with the model by an RMS \
                 of {rms_deg:.1} deg: no geometry of this robot fits them, so they are most \
                 likely not ZYX Euler angles (alpha about z, then beta about y, then gamma about \
                 x) of the measured frame; convert them, or use the positions alone"
            ),
            Warning::PositionsUnfit { rms, reach, unit } => write!(
                f,
                "after calibration the measured positions still disagree with the model by an RMS \
                 of {rms:.6} {unit}, {:.0} % of the robot's reach ({reach:.6} {unit}): a model that \
                 fits this robot does far better, so the solver stopped at a local minimum of a \
                 start far from the robot, or the data are not this robot's; check the units of \
                 the readings and positions and the robot file, or start from values nearer the \
                 robot's (--initial)",
                100.0 * rms / reach.max(f64::MIN_POSITIVE)
            ),
            Warning::Restarted { starts, kept } => write!(
                f,
                "the fit from the given start ended with the positions unfit, so it was tried from \
                 {} starts in all (objective reached, RMS position error): {}; kept {kept}",
                starts.len(),
                starts
                    .iter()
                    .map(|s| format!(
                        "{} {:.4e}, {:.6}{}",
                        s.start,
                        s.objective,
                        s.rms_position,
                        if s.converged { "" } else { " (not converged)" }
                    ))
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
            Warning::RankLost { start_rank, rank } => write!(
                f,
                "the solver stopped where the Jacobian determines {rank} directions, {start_rank} \
                 at the start: the model lost a direction on the way (two joint axes lined up, a \
                 frame folded onto another) and the result is not a minimum to trust; start from \
                 values nearer the robot's (--initial) or estimate fewer parameters"
            ),
            Warning::PooledPlacements {
                blocks,
                rms_pooled,
                rms_per_block,
                unit,
            } => write!(
                f,
                "the postures fall into {} groups, each fitted far better by a placement of the \
                 measurement frame of its own ({rms_per_block:.6} {unit} RMS, the robot held) \
                 than by one for all ({rms_pooled:.6} {unit}): {}; the instrument was most \
                 likely moved between them (not a unit mix-up). Add a `session` column naming \
                 each placement, so that each gets a frame of its own",
                blocks.len(),
                blocks.join(", ")
            ),
            Warning::WorseOnValidation {
                metric,
                before,
                after,
                unit,
            } => write!(
                f,
                "the calibration made the held-out {metric} errors worse: mean {before:.6} -> \
                 {after:.6} {unit}; the model fits the identification data but not other \
                 postures (too many parameters for the data, postures that do not cover the \
                 workspace, or the validation data measured differently)"
            ),
            Warning::ModelErrorFloor {
                scale,
                length_mm,
                angle_deg,
                rows,
                above,
            } => {
                let mut parts = Vec::new();
                if *length_mm > 0.0 {
                    parts.push(format!("{length_mm:.4} mm on lengths"));
                }
                if *angle_deg > 0.0 {
                    parts.push(format!("{angle_deg:.5} deg on angles"));
                }
                write!(
                    f,
                    "the rows' own standard deviations are {scale:.0} times below their residuals \
                     (they state the instrument's noise, not the model's): each such row was \
                     weighted by max(sigma, m), with a model error m estimated from the \
                     residuals: {}; {}; model_error = \"none\" weighs them as stated",
                    parts.join(", "),
                    if *above == 0 {
                        format!("every one of the {rows} rows states less, so they weigh alike")
                    } else {
                        format!("{above} of the {rows} rows state more and keep their own")
                    }
                )
            }
            Warning::ChosenAtResidualNoise { scale, left_out } => write!(
                f,
                "the residuals of a first fit were {scale:.0} times the stated standard \
                 deviations: the identifiable set was chosen again at that noise, leaving out {} \
                 (determined only at the stated precision), and fitted again",
                left_out.join(", ")
            ),
            Warning::SigmasOff { variance_factor } => {
                let k = variance_factor.sqrt();
                if k > 1.0 {
                    write!(
                        f,
                        "the residuals are {k:.0} times the stated standard deviations (variance \
                         factor {variance_factor:.4}): the parameters' sigmas are scaled to the \
                         residuals, but the outliers listed and the relative weights of rows are \
                         judged with the stated ones; state sigmas near the residuals' size \
                         (--weights, or the files' sigma columns)"
                    )
                } else {
                    write!(
                        f,
                        "the residuals are {:.0} times smaller than the stated standard \
                         deviations (variance factor {variance_factor:.4}): the weights do not \
                         describe this data; state sigmas near the residuals' size (--weights, \
                         or the files' sigma columns)",
                        1.0 / k
                    )
                }
            }
            Warning::AngleUnitMismatch {
                joints,
                file_unit,
                looks_like,
            } => write!(
                f,
                "the readings of joint(s) {} look like {looks_like} but the robot file reads them \
                 as {file_unit} (slope 1): convert them, or set the slopes (the offsets would \
                 otherwise absorb whole turns)",
                joints
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Warning::PlacedLoose { parameters } => write!(
                f,
                "estimated although the data determine them too loosely for the identifiable \
                 set's noise rule: {}; the start's closed-form placement had set them from the \
                 data with the nominal robot, and held there they would keep that fit's error \
                 (more varied postures determine them: other tool attitudes, for a tool's \
                 length along its axis)",
                parameters.join(", ")
            ),
            Warning::ChangeBeyondReach {
                parameters,
                reach,
                unit,
            } => write!(
                f,
                "{} moved by more than the robot's reach ({reach:.4} {unit}): not a calibration \
                 of this robot (units, a wrong model, or a far start)",
                parameters.join(", ")
            ),
            Warning::NegativeCompliance { parameters } => write!(
                f,
                "negative compliances: {} (a joint that turns against gravity's torque); the data \
                 does not determine them: hold them, or give them a prior (--prior \
                 compliance=...)",
                parameters.join(", ")
            ),
            Warning::SlopeFarOff { parameters } => write!(
                f,
                "slopes changed by more than {:.0} % of the robot file's: {} (readings in another \
                 unit or scale, a gear ratio, or a coupling the model lacks; hold the slopes, or \
                 give them a prior: --prior slope=0.01)",
                SLOPE_CHANGE * 100.0,
                parameters.join(", ")
            ),
            Warning::LargeDeflection { degrees } => write!(
                f,
                "a joint deflects by {degrees:.2} deg under gravity (beyond {:.1} deg): the \
                 compliances or masses are not physical; give them a prior (--prior \
                 compliance=...) or fix the masses (--total-mass)",
                DEFLECTION_LIMIT.to_degrees()
            ),
            Warning::LooseAndMoved { parameters } => write!(
                f,
                "determined worse than the robot's tolerances and moved by over {LOOSE_MOVE_SIGMAS} \
                 of their standard deviations: {} (the data barely holds them: a prior, e.g. \
                 --prior tolerances, or more postures)",
                parameters.join(", ")
            ),
            Warning::ValidationTargetsUnseen { targets } => write!(
                f,
                "validation targets no identification row measures: {} (their frames were never \
                 identified; their errors are the nominal frames', not the calibration's: \
                 measure them in the identification data too)",
                targets.join(", ")
            ),
            Warning::Unseen { parameters } => write!(
                f,
                "not estimated by default, as no observation sees them: {} (name them to estimate \
                 them anyway)",
                parameters.join(", ")
            ),
            Warning::Unfelt { parameters } => write!(
                f,
                "no observation feels {}: these parameters stay at their initial values",
                parameters.join(", ")
            ),
            Warning::UnclearRank {
                rank,
                rcond,
                gap_rank,
                gap_ratio,
            } => write!(
                f,
                "the rank from the tolerance ({rank}, rcond {rcond:e}) differs from the largest gap \
                 in the spectrum (after singular value {gap_rank}, ratio {gap_ratio:.3e}): the \
                 split between determined and undetermined directions is not clear-cut; more, \
                 better spread postures would help"
            ),
            Warning::SmallGap { rank, gap_ratio } => write!(
                f,
                "the gap at rank {rank} is only a factor {gap_ratio:.3e}: nearly-undetermined \
                 directions are hard to tell from undetermined ones"
            ),
            Warning::BarelyDetermined { ratio } => write!(
                f,
                "full rank, but the smallest scaled singular value is {ratio:.3e} of the largest: \
                 some combinations are barely determined"
            ),
            Warning::EulerSingular { frame } => write!(
                f,
                "{frame} has beta within 0.06 deg of +-90 deg: its alpha and gamma rotate about \
                 the same axis (gimbal lock of the Euler parameterisation), so they cannot be told \
                 apart; this is a singularity of the parameterisation, not a physical redundancy: \
                 choose that frame's axes so that beta is away from +-90 deg"
            ),
            Warning::Correlated { a, b, rho } => write!(
                f,
                "{a} and {b} are correlated {rho:+.3}: the data barely separates them"
            ),
            Warning::NotConverged { iterations } => write!(
                f,
                "the solver stopped at the iteration cap ({iterations}) before converging"
            ),
            Warning::EquilibriumNotConverged { postures, of } => write!(
                f,
                "the gravity equilibrium did not converge to 1e-10 rad at {postures} of {of} \
                 postures: the compliances are implausibly large (or the robot would buckle); \
                 the deflections there are unreliable"
            ),
            Warning::Stalled { method } => write!(
                f,
                "the {method} steps stopped reducing the objective where a Levenberg-Marquardt \
                 step still does: the result is not a minimum"
            ),
            Warning::NoUncertainty { reason } => write!(f, "no uncertainty: {reason}"),
            Warning::NoPrediction { reason } => write!(f, "no predicted accuracy: {reason}"),
            Warning::ExactFit => write!(
                f,
                "as many independent residuals as determined parameters: the fit is exact and no \
                 standard deviation can be estimated"
            ),
            Warning::UrdfSlope { joint, name, slope } => write!(
                f,
                "joint {joint} (`{name}`) has slope {slope} rad or m per unit: a URDF cannot scale \
                 joint values, so the controller must"
            ),
            Warning::UrdfCoupled { joint, name, other } => write!(
                f,
                "joint {joint} (`{name}`) is coupled to joint {other}: the URDF joint's value is \
                 the sum of the two readings (as controller drivers for coupled arms publish it)"
            ),
            Warning::UrdfToolAdded { link } => write!(
                f,
                "the tip link is the child of the last movable joint: the calibrated tool frame \
                 is the added link `{link}` (fixed joint `{link}_joint`)"
            ),
        }
    }
}
