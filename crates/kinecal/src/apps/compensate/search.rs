//! Cartesian targets: the search over a robot's solutions for the one a controller can use.
//!
//! A Cartesian goal has several solutions (configurations, and whole turns of revolute
//! joints); the damped least squares of [`Compensator`] finds the one nearest where it starts.
//! [`TargetSearch`] starts it from several places and keeps a solution that is *usable*:
//! reached within the tolerances, inside the robot file's joint ranges, in the configuration
//! asked for (if any), with a seed in the seed's configuration (no revolute joint turned more
//! than [`Options::branch`] from it), and away from singularities. In this order:
//!
//! 1. From the *reference*: the seed readings given with the target, else the previous
//!    target's solution (when it lies nearer the goal than any start below: a path). With a
//!    seed this is the minimum change from the seed (for a redundant arm too).
//! 2. From the sampled postures whose target frames lie nearest the goal (a table of
//!    [`TargetSearch::STARTS`] postures drawn within the joint ranges, built once per target
//!    frame; nearness is the position distance plus the reach times the attitude angle),
//!    up to [`TargetSearch::ATTEMPTS`] of them; with a configuration asked for, the table
//!    holds postures in it only.
//! 3. When none of those is usable: [`TargetSearch::SPREAD`] starts spread over the table.
//!
//! With a seed, the table is looked at only when the seed's own solution is not usable, and
//! then briefly: [`TargetSearch::SEEDED_ATTEMPTS`] nearest starts and
//! [`TargetSearch::SEEDED_SPREAD`] spread ones at most, stopping at the first solution that is
//! usable, or reached inside the ranges and the configuration and flagged only for a change of
//! configuration or only for a singularity (a solution usable with this seed lies within
//! [`Options::branch`] of it, where the seed's own attempt and the nearest starts look).
//! Without a seed the search stops at the first usable solution; a goal reached, in range and
//! in configuration but singular from the first 9 nearest starts skips the rest of them.
//!
//! Every solution has its revolute readings moved by whole turns (which leave the pose as it
//! is) to the turn nearest the reference, then into the joint's range when that turn is
//! outside it; a joint without a range in the robot file stays within half a turn of its
//! reading range's middle (see [`crate::apps::simulate::reading_range`]), so that no reading comes
//! back several turns away. The first usable solution is taken (from step 1 when it is
//! usable: the seed's, or the previous solution's neighbour). When none is usable, the least
//! bad of the attempts made is returned with its flags (the nearest the reference among
//! equally bad ones), in
//! the order: unreachable, outside a range, not in the configuration, a change of
//! configuration from the seed given, near a singularity; so
//! `unreachable` means that no start reached the goal, and `outside range` that every solution
//! found needs a joint beyond its range.

use super::configuration::Classifier;
use super::{Compensator, Configuration, Flags, Goal, Options, Solved};
use crate::error::Result;
use crate::model::kinematics::{Target, Workspace};
use crate::model::robot::{JointKind, Robot};

/// Starts, targets' frames and the search's work space for one calibrated robot.
pub struct TargetSearch<'r> {
    comp: Compensator<'r>,
    robot: &'r Robot,
    options: Options,
    /// Reading ranges starts are drawn from (the file's, else [`crate::apps::simulate::reading_range`]).
    middle: Vec<f64>,
    /// Readings per whole turn of each revolute joint whose reading no other joint couples to.
    turn: Vec<Option<f64>>,
    /// Start postures, `STARTS` rows of `dof` readings.
    starts: Vec<f64>,
    /// Per target frame: the start postures' frames, 12 numbers each (position, rotation).
    tables: Vec<(Target, Vec<[f64; 12]>)>,
    classifier: Option<Classifier>,
    previous: Option<Vec<f64>>,
    reference: Vec<f64>,
    /// Whether the goal being solved came with a seed (the reference).
    seeded: bool,
    candidate: Vec<f64>,
    start: Vec<f64>,
    /// An attempt's start, with the joints that do not move the target at the reference.
    from: Vec<f64>,
    nearest: Vec<(f64, u32)>,
    ws: Workspace,
}

/// How good a solution is, best first: `(unreachable, outside a range, not in the
/// configuration, a change of configuration from the seed, singular)`, then the distance to the
/// reference.
type Rank = ([bool; 5], f64);

impl<'r> TargetSearch<'r> {
    /// Start postures in the table.
    pub(crate) const STARTS: usize = 4096;
    /// Starts from the table tried at most per goal.
    pub(crate) const ATTEMPTS: usize = 32;
    /// Starts spread over the table tried after the nearest ones found nothing usable.
    pub const SPREAD: usize = 32;
    /// Iteration cap of the damped least squares from a start of the table.
    pub(crate) const CAP: usize = 30;
    /// With a seed whose own solution is not usable: starts of the table tried at most,
    /// nearest first ...
    pub(crate) const SEEDED_ATTEMPTS: usize = 8;
    /// ... and then spread over the table.
    pub(crate) const SEEDED_SPREAD: usize = 4;

    /// A search for `calibrated`; `nominal` is the model the targets' programs were made with
    /// (same structure).
    pub fn new(calibrated: &'r Robot, nominal: &'r Robot, options: Options) -> Result<Self> {
        let comp = Compensator::new(calibrated, nominal, options)?;
        let dof = calibrated.dof();
        let middle = (0..dof)
            .map(|j| {
                let (lo, hi) = crate::apps::simulate::reading_range(calibrated, j);
                0.5 * (lo + hi)
            })
            .collect();
        let coupled_to: Vec<bool> = (0..dof)
            .map(|k| {
                calibrated
                    .joints
                    .iter()
                    .any(|j| j.coupling.is_some_and(|c| c.joint == k))
            })
            .collect();
        let turn = calibrated
            .joints
            .iter()
            .zip(&coupled_to)
            .map(|(j, &c)| {
                (j.kind == JointKind::Revolute && !c && j.slope != 0.0)
                    .then(|| std::f64::consts::TAU / j.slope.abs())
            })
            .collect();
        let starts = crate::apps::simulate::sample_postures(calibrated, Self::STARTS, 7919)
            .into_iter()
            .flat_map(|p| p.readings)
            .collect();
        Ok(TargetSearch {
            comp,
            robot: calibrated,
            options,
            middle,
            turn,
            starts,
            tables: Vec::new(),
            classifier: None,
            previous: None,
            reference: vec![0.0; dof],
            seeded: false,
            candidate: vec![0.0; dof],
            start: vec![0.0; dof],
            from: vec![0.0; dof],
            nearest: Vec::with_capacity(Self::ATTEMPTS + 1),
            ws: Workspace::new(calibrated),
        })
    }

    /// Solutions must be in `configuration` (checked against the robot: a named one needs an
    /// arm of six revolute joints).
    pub fn with_configuration(mut self, configuration: Configuration) -> Result<Self> {
        let c = Classifier::new(self.robot, configuration)?;
        // Starts in the configuration only (the solver tends to stay in its start's): drawn
        // within the ranges until the table is full, or 64 tables' worth were drawn.
        let dof = self.robot.dof();
        let mut starts = Vec::with_capacity(Self::STARTS * dof);
        for batch in 0..64 {
            for p in crate::apps::simulate::sample_postures(self.robot, Self::STARTS, 7919 + batch)
            {
                self.comp.calibrated.forward(&p.readings, &mut self.ws);
                if c.matches(self.robot, &p.readings, &self.ws) {
                    starts.extend_from_slice(&p.readings);
                    if starts.len() == Self::STARTS * dof {
                        break;
                    }
                }
            }
            if starts.len() == Self::STARTS * dof {
                break;
            }
        }
        if !starts.is_empty() {
            self.starts = starts;
            self.tables.clear();
        }
        self.classifier = Some(c);
        Ok(self)
    }

    /// What the tool carries for the goals that follow ([`Compensator::set_payload`]). The
    /// table of starts stays the unloaded robot's: it only chooses where to start.
    pub(crate) fn set_payload(&mut self, payload: Option<crate::model::robot::Payload>) {
        self.comp.set_payload(payload);
    }

    /// The configuration asked for, if any.
    pub fn configuration(&self) -> Option<&Configuration> {
        self.classifier.as_ref().map(|c| c.configuration())
    }

    /// Writes into `out` a usable solution of `goal` for `target` (see the module's
    /// documentation), starting from `seed` when given. A reached solution becomes the
    /// reference of the next unseeded goal.
    pub fn solve(
        &mut self,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        out: &mut [f64],
    ) -> Solved {
        let dof = self.robot.dof();
        assert_eq!(out.len(), dof);
        self.ensure_table(target);
        self.seeded = seed.is_some();
        // The table's nearest starts are looked up only when needed: a seed that converges
        // needs none.
        let mut looked_up = false;
        // Step 1: the reference, when it is one.
        let from_reference = match (seed, &self.previous) {
            (Some(s), _) => {
                self.reference.copy_from_slice(s);
                true
            }
            (None, Some(p)) => {
                self.reference.copy_from_slice(p);
                self.find_nearest(goal, target);
                looked_up = true;
                let reference = std::mem::take(&mut self.reference);
                let d = self.distance_of(goal, target, &reference);
                self.reference = reference;
                self.nearest.first().is_none_or(|&(best, _)| d <= best)
            }
            (None, None) => {
                self.reference.copy_from_slice(&self.middle);
                false
            }
        };
        let mut best: Option<(Rank, Solved)> = None;
        if from_reference {
            let mut start = std::mem::take(&mut self.start);
            start.copy_from_slice(&self.reference);
            let s = self.attempt(goal, target, &start, true);
            self.start = start;
            if self.consider(s, seed.is_some(), &mut best, out) {
                return self.finish(best.expect("considered").1, out);
            }
        }
        if !looked_up {
            self.find_nearest(goal, target);
        }
        // Whether the search can stop without a usable solution: without a seed, once the
        // goal shows itself at a singularity (reached, in range and configuration, and singular
        // from 8 starts); with a seed, once a solution is reached in range and configuration,
        // flagged only for its change of configuration or only for a singularity (a usable one
        // lies within the box of starts just tried).
        let settled = |best: &Option<(Rank, Solved)>, tried: usize| {
            best.as_ref().is_some_and(|(r, _)| {
                let f = r.0;
                let placed = !f[0] && !f[1] && !f[2];
                if seed.is_some() {
                    placed && (!f[3] || !f[4])
                } else {
                    placed && !f[3] && f[4] && tried > 8
                }
            })
        };
        // Step 2: the nearest starts of the table.
        let mut usable = false;
        let mut tried = 0;
        for k in 0..self.nearest.len() {
            if seed.is_some() && k >= Self::SEEDED_ATTEMPTS {
                break;
            }
            let i = self.nearest[k].1 as usize;
            usable |= self.attempt_start(i, goal, target, seed, &mut best, out);
            tried += 1;
            if usable && seed.is_none() {
                break;
            }
            if settled(&best, tried) {
                break;
            }
        }
        // Step 3: nothing usable near the goal: starts spread over the whole table.
        let rows = self.starts.len() / dof;
        if !usable && rows > 0 && !(seed.is_some() && settled(&best, tried)) {
            for k in 0..Self::SPREAD {
                if seed.is_some() && k >= Self::SEEDED_SPREAD {
                    break;
                }
                let i = (k * rows / Self::SPREAD + rows / (2 * Self::SPREAD)) % rows;
                usable |= self.attempt_start(i, goal, target, seed, &mut best, out);
                if (usable && seed.is_none()) || (seed.is_some() && settled(&best, tried)) {
                    break;
                }
            }
        }
        let (rank, mut solved) = best.expect("at least one attempt");
        if rank.0[0] {
            // Nothing reached within the search's iteration cap: the best attempt gets the
            // full cap (near a singularity the solver converges slowly).
            let mut start = std::mem::take(&mut self.start);
            start.copy_from_slice(out);
            let s = self.attempt(goal, target, &start, false);
            self.start = start;
            // The damped least squares never increases the error: the polished one is better.
            out.copy_from_slice(&self.candidate);
            solved = s;
        }
        self.finish(solved, out)
    }

    /// One attempt from start `i` of the table, within the search's iteration cap; whether its
    /// solution is usable (kept in `out` when it ranks before `best`).
    fn attempt_start(
        &mut self,
        i: usize,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        best: &mut Option<(Rank, Solved)>,
        out: &mut [f64],
    ) -> bool {
        let dof = self.robot.dof();
        let starts = std::mem::take(&mut self.starts);
        let s = self.attempt_capped(goal, target, &starts[i * dof..(i + 1) * dof]);
        self.starts = starts;
        self.consider(s, seed.is_some(), best, out)
    }

    /// [`TargetSearch::attempt`] from `start` within the search's iteration cap: a start that
    /// has not converged in [`Self::CAP`] iterations is in another basin.
    fn attempt_capped(&mut self, goal: &Goal, target: Target, start: &[f64]) -> Solved {
        let cap = self.options.max_iterations;
        self.comp.options.max_iterations = cap.min(Self::CAP);
        let s = self.attempt(goal, target, start, false);
        self.comp.options.max_iterations = cap;
        s
    }

    /// Keeps the candidate in `out` when it ranks before `best`; whether it is usable.
    fn consider(
        &self,
        solved: Solved,
        seeded: bool,
        best: &mut Option<(Rank, Solved)>,
        out: &mut [f64],
    ) -> bool {
        let rank = self.rank(&solved, seeded);
        let usable = rank.0 == [false; 5];
        if best.as_ref().is_none_or(|(b, _)| rank < *b) {
            out.copy_from_slice(&self.candidate);
            *best = Some((rank, solved));
        }
        usable
    }

    /// Records the solution of a reached goal as the next reference.
    fn finish(&mut self, solved: Solved, out: &[f64]) -> Solved {
        if !solved.flags.unreachable {
            self.previous
                .get_or_insert_with(|| vec![0.0; out.len()])
                .copy_from_slice(out);
        }
        solved
    }

    /// One local solution from `start` into `self.candidate`, its turns moved and its flags
    /// set (`branch` against a seed given).
    fn attempt(&mut self, goal: &Goal, target: Target, start: &[f64], nearest: bool) -> Solved {
        let mut candidate = std::mem::take(&mut self.candidate);
        // A tree's joints on other branches cannot move the target: they start, and so stay,
        // at the reference (the seed, the previous row's solution, or mid-range).
        let mut from = std::mem::take(&mut self.from);
        from.copy_from_slice(start);
        if self.robot.is_tree() {
            let attach = crate::model::kinematics::target_joint(self.robot, target);
            for (j, v) in from.iter_mut().enumerate() {
                if !self.robot.joint_moves(j, attach) {
                    *v = self.reference[j];
                }
            }
        }
        let mut s = self
            .comp
            .local(goal, target, &from, nearest, &mut candidate);
        self.from = from;
        for (j, joint) in self.robot.joints.iter().enumerate() {
            let v = &mut candidate[j];
            if let Some(t) = self.turn[j] {
                *v += t * ((self.reference[j] - *v) / t).round();
                let (lo, hi) = joint
                    .range
                    .unwrap_or((self.middle[j] - 0.5 * t, self.middle[j] + 0.5 * t));
                // Into the range when a whole turn gets it there; else the reference's turn.
                let moved = if *v < lo {
                    *v + t * ((lo - *v) / t).ceil()
                } else if *v > hi {
                    *v - t * ((*v - hi) / t).ceil()
                } else {
                    *v
                };
                if (lo..=hi).contains(&moved) {
                    *v = moved;
                }
            }
            if let Some((lo, hi)) = joint.range {
                if *v < lo || *v > hi {
                    s.flags.out_of_range |= 1 << j;
                }
            }
        }
        if self.seeded {
            // A change of configuration from the seed given (the reference).
            for (j, joint) in self.robot.joints.iter().enumerate() {
                if joint.kind == JointKind::Revolute {
                    let moved = joint.value(&candidate, j) - joint.value(&self.reference, j);
                    s.flags.branch |= moved.abs() > self.options.branch;
                }
            }
        }
        if let Some(c) = &self.classifier {
            // The geometry does not change with whole turns: the solver's last forward
            // kinematics is the solution's.
            s.flags.configuration = !c.matches(self.robot, &candidate, &self.comp.ws);
        }
        self.candidate = candidate;
        s
    }

    fn rank(&self, s: &Solved, seeded: bool) -> Rank {
        let f: &Flags = &s.flags;
        let distance = if seeded || self.previous.is_some() {
            self.candidate
                .iter()
                .zip(&self.reference)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
        } else {
            0.0
        };
        (
            [
                f.unreachable,
                f.out_of_range != 0,
                f.configuration,
                f.branch,
                f.singular,
            ],
            distance,
        )
    }

    /// Builds the table of start frames for `target` (once).
    fn ensure_table(&mut self, target: Target) {
        if self.tables.iter().any(|(t, _)| *t == target) {
            return;
        }
        let dof = self.robot.dof();
        let starts = std::mem::take(&mut self.starts);
        let table = starts
            .chunks_exact(dof)
            .map(|r| self.frame_key(r, target))
            .collect();
        self.starts = starts;
        self.tables.push((target, table));
    }

    /// Fills `self.nearest` with the [`Self::ATTEMPTS`] starts nearest `goal`, nearest first.
    fn find_nearest(&mut self, goal: &Goal, target: Target) {
        let table = &self
            .tables
            .iter()
            .find(|(t, _)| *t == target)
            .expect("built")
            .1;
        let reach2 = self.comp.reach * self.comp.reach;
        self.nearest.clear();
        let p = match goal {
            Goal::Position(p) => p,
            Goal::Pose(g) => &g.translation,
        };
        for (i, k) in table.iter().enumerate() {
            // The position part first: a start already farther than the last kept one by its
            // position alone is passed over without its attitude term (which is never negative).
            let dp = (p.x - k[0]).powi(2) + (p.y - k[1]).powi(2) + (p.z - k[2]).powi(2);
            if self.nearest.len() == Self::ATTEMPTS && dp >= self.nearest[Self::ATTEMPTS - 1].0 {
                continue;
            }
            let d = key_distance(goal, k, reach2);
            if self.nearest.len() == Self::ATTEMPTS {
                if d >= self.nearest[Self::ATTEMPTS - 1].0 {
                    continue;
                }
                self.nearest.pop();
            }
            let at = self.nearest.partition_point(|&(e, _)| e <= d);
            self.nearest.insert(at, (d, i as u32));
        }
    }

    /// The squared task distance from the frame `target` has at `readings` to `goal`.
    fn distance_of(&mut self, goal: &Goal, target: Target, readings: &[f64]) -> f64 {
        let k = self.frame_key(readings, target);
        key_distance(goal, &k, self.comp.reach * self.comp.reach)
    }

    /// The frame `target` has at `readings` through the calibrated model, as a table key:
    /// position, then the rotation's columns.
    fn frame_key(&mut self, readings: &[f64], target: Target) -> [f64; 12] {
        let chain = &self.comp.calibrated;
        chain.forward(readings, &mut self.ws);
        let f = chain.target_frame(&self.ws, target);
        let mut k = [0.0; 12];
        k[..3].copy_from_slice(f.translation.as_slice());
        k[3..].copy_from_slice(f.rotation.as_slice());
        k
    }
}

/// Squared position distance plus `reach^2 (3 - tr(R_goal^T R))`, which is `reach^2 theta^2`
/// to second order in the attitude angle `theta`.
fn key_distance(goal: &Goal, k: &[f64; 12], reach2: f64) -> f64 {
    match goal {
        Goal::Position(p) => (p.x - k[0]).powi(2) + (p.y - k[1]).powi(2) + (p.z - k[2]).powi(2),
        Goal::Pose(g) => {
            let p = &g.translation;
            let r = g.rotation.as_slice();
            let trace: f64 = r.iter().zip(&k[3..]).map(|(a, b)| a * b).sum();
            (p.x - k[0]).powi(2)
                + (p.y - k[1]).powi(2)
                + (p.z - k[2]).powi(2)
                + reach2 * (3.0 - trace)
        }
    }
}
