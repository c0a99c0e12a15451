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
//!
//!    For a pose goal on a robot whose nominal model has a closed form (a spherical wrist or
//!    a UR-type arm: see the `analytic` module), its eight branches are the next starts (with
//!    a seed, unless the seed's own solution was reached at a singularity; without one,
//!    before the previous solution, which is tried only when the branches do not settle the
//!    goal), refined on the calibrated model, in the order: branches the nominal robot
//!    reaches, predicted inside the ranges, in the configuration, not turned from the seed,
//!    then nearest the reference (a branch at the seed itself, as a program's readings are
//!    for the pose the nominal model gives them, is not refined again: the seed's own attempt
//!    stands for it). Any other arm of six revolute joints has the general form (the
//!    `general` module), which needs no special geometry: its branches are the calibrated
//!    arm's own solutions (of its rigid geometry), up to 16, and they are *complete* when
//!    the form can tell that they are all the arm has (every root of its polynomial told
//!    apart; 940 of 1,000 random goals); with a seed, branches not complete are not tried.
//!    The first usable one is taken. When none is, the best is kept without looking further
//!    if the branches are complete, every branch the nominal robot reaches refined to a
//!    solution of its own and the best is flagged only for a range or a change from the seed
//!    (or, without a seed, on the general form of an arm without an elastic model, at a
//!    singularity: its branches are then all the arm's solutions), or, with a seed, if
//!    neither the seed nor any branch reached the goal though the nominal robot reaches it
//!    exactly (the calibrated robot's solutions lie near the
//!    nominal's: the goal is beyond its reach, typically by a fraction of a millimetre at a
//!    stretched elbow, which the reach bound below cannot prove); otherwise (near a
//!    singularity the calibrated robot may have solutions the nominal one has not) the table
//!    below is searched as for any robot, and, with a seed its own attempt did not reach,
//!    until the table's starts settle it as they would without the branches.
//! 2. From the sampled postures whose target frames lie nearest the goal (a table of
//!    [`TargetSearch::STARTS`] postures drawn within the joint ranges, built once per target
//!    frame; nearness is the position distance plus the reach times the attitude angle),
//!    up to [`TargetSearch::ATTEMPTS`] of them; with a configuration asked for, the table
//!    holds postures in it only.
//! 3. When none of those is usable: [`TargetSearch::SPREAD`] starts spread over the table.
//!
//! A pose goal that the calibrated arm's reach bound (the `reach` module: its wrist point too
//! far from, or too near, its shoulder for any posture) proves out of reach is tried once: from
//! its seed; without one, from the previous goal's solution where step 1 takes it as the
//! reference, else from the table's nearest start; and that attempt polished as below: no start
//! can reach it.
//!
//! With a seed, the table is looked at only when the seed's own solution is not usable, and
//! then briefly: [`TargetSearch::SEEDED_ATTEMPTS`] nearest starts and
//! [`TargetSearch::SEEDED_SPREAD`] spread ones at most, stopping at the first solution that is
//! usable, or reached inside the ranges and the configuration and flagged only for a change of
//! configuration or only for a singularity (a solution usable with this seed lies within
//! [`Options::branch`] of it, where the seed's own attempt and the nearest starts look).
//! Without a seed the search stops at the first usable solution; a goal reached, in range and
//! in configuration but singular from the first 9 nearest starts skips the rest of them, and,
//! when the closed form's branches were tried too (none usable) and are complete, the spread
//! ones (the goal lies at a singularity: on the IRB 120 and the UR10 of the compensate bench
//! the spread starts found no other solution for any such goal). On an arm without an elastic
//! model, the general form's complete branches are every solution the arm has: when each
//! refines to a reached solution of its own and the best is flagged only at a singularity (or
//! for a range), the goal is settled without the table (on the random 6R arm of the
//! compensate bench its 23 such goals keep their flags and solutions, at 147 forward
//! kinematics each instead of 490).
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

use super::analytic::{Analytic, Family, MOST};
use super::configuration::Classifier;
use super::reach::ReachBound;
use super::start_table::StartTable;
use super::{Compensator, Configuration, Flags, Goal, Options, Solved};
use crate::error::Result;
use crate::model::kinematics::{Target, Workspace};
use crate::model::robot::{JointKind, Robot};

/// Starts, targets' frames and the search's work space for one calibrated robot.
pub struct TargetSearch<'r> {
    comp: Compensator<'r>,
    robot: &'r Robot,
    nominal: &'r Robot,
    /// Per target frame: the nominal robot's closed form, when it has one (of a family; for
    /// the general form, the calibrated robot's own).
    closed_forms: Vec<(Target, Option<Analytic>)>,
    /// Whether pose goals start from the closed form's branches (tests turn it off to compare
    /// with the search alone).
    use_closed_form: bool,
    /// Per target frame: the calibrated arm's reach bound, when it has one.
    reach_bounds: Vec<(Target, Option<ReachBound>)>,
    /// Whether goals the reach bound proves out of reach skip the search (tests turn it off to
    /// compare with the search's verdict).
    use_reach_bound: bool,
    /// Whether a goal at a singularity, shown so by complete closed-form branches, skips
    /// starts of the table: unseeded, settled by the nearest starts, the spread ones; on a rigid
    /// arm's general form, whose branches are then all its solutions, every start (tests turn it
    /// off to compare).
    skip_table_if_singular: bool,
    /// Goals the closed form's branches settled with their best at a singularity.
    #[cfg(test)]
    settled_at_singularity: usize,
    /// Whether a seeded goal whose seed does not reach it is tried from the closed form's
    /// branches, and the search ends there when none reaches it either (tests turn it off to
    /// compare with the table's starts tried instead).
    branches_when_seed_fails: bool,
    /// Whether the closed form's branch at the seed itself is refined again (tests turn it on
    /// to compare: the seed's own attempt stands for it).
    refine_seed_branch: bool,
    options: Options,
    /// Reading ranges starts are drawn from (the file's, else [`crate::apps::simulate::reading_range`]).
    middle: Vec<f64>,
    /// Readings per whole turn of each revolute joint whose reading no other joint couples to.
    turn: Vec<Option<f64>>,
    /// Start postures, `STARTS` rows of `dof` readings.
    starts: Vec<f64>,
    /// Per target frame: the start postures' frames, indexed by position.
    tables: Vec<(Target, StartTable)>,
    classifier: Option<Classifier>,
    previous: Option<Vec<f64>>,
    reference: Vec<f64>,
    /// Whether the goal being solved came with a seed (the reference).
    seeded: bool,
    candidate: Vec<f64>,
    start: Vec<f64>,
    /// An attempt's start, with the joints that do not move the target at the reference.
    from: Vec<f64>,
    /// The starts nearest the goal, nearest first: the first [`Self::FIRST_NEAREST`] of them
    /// until more are needed.
    nearest: Vec<(f64, u32)>,
    /// How many starts `nearest` was looked up for.
    nearest_asked: usize,
    ws: Workspace,
    /// The normal matrix at the best solution so far (its conditioning, when deferred, is
    /// worked out from it once the search ends).
    best_normal: nalgebra::Matrix6<f64>,
}

/// How good a solution is, best first: `(unreachable, outside a range, not in the
/// configuration, a change of configuration from the seed, singular)`, then the distance to the
/// reference.
type Rank = ([bool; 5], f64);

/// How bad a solution's flags are, as the search ranks them (see [`Rank`]).
fn flag_rank(f: &Flags) -> [bool; 5] {
    [
        f.unreachable,
        f.out_of_range != 0,
        f.configuration,
        f.branch,
        f.singular,
    ]
}

/// Whether a solution of this rank is usable: flagged for nothing.
fn usable(rank: &Rank) -> bool {
    rank.0 == [false; 5]
}

/// Keeps in `judged` the better of it and `rank`.
fn lower(judged: &mut Option<Rank>, rank: Rank) {
    if judged.is_none_or(|j| rank < j) {
        *judged = Some(rank);
    }
}

/// Whether the search can stop without a usable solution, by the best rank `judged` so far
/// after `tried` of the table's nearest starts: without a seed, once the goal shows itself at a
/// singularity (reached, in range and configuration, and singular from 9 starts); with a seed
/// (`seeded`), once a solution is reached in range and configuration, flagged only for its
/// change of configuration or only for a singularity (a usable one lies within the box of
/// starts just tried).
fn settled(judged: &Option<Rank>, tried: usize, seeded: bool) -> bool {
    judged.as_ref().is_some_and(|r| {
        let f = r.0;
        let placed = !f[0] && !f[1] && !f[2];
        if seeded {
            placed && (!f[3] || !f[4])
        } else {
            placed && !f[3] && f[4] && tried > 8
        }
    })
}

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
    /// The nearest starts looked up first; the rest of [`Self::ATTEMPTS`] (or
    /// [`Self::SEEDED_ATTEMPTS`]) only for a goal none of them settles (most goals need one or
    /// two, and a lookup that keeps fewer looks at fewer starts).
    pub(crate) const FIRST_NEAREST: usize = 4;

    /// A search for `calibrated`; `nominal` is the model the targets' programs were made with
    /// (same structure).
    pub fn new(calibrated: &'r Robot, nominal: &'r Robot, options: Options) -> Result<Self> {
        let mut comp = Compensator::new(calibrated, nominal, options)?;
        // Many attempts are judged, one reported: its conditioning is worked out at the end.
        comp.defer_conditioning = true;
        let dof = calibrated.dof();
        let middle = (0..dof)
            .map(|j| {
                let (lo, hi) = crate::apps::simulate::reading_range(calibrated, j);
                0.5 * (lo + hi)
            })
            .collect();
        let turn = super::whole_turns(calibrated);
        let starts = crate::apps::simulate::sample_postures(calibrated, Self::STARTS, 7919)
            .into_iter()
            .flat_map(|p| p.readings)
            .collect();
        Ok(TargetSearch {
            comp,
            robot: calibrated,
            nominal,
            closed_forms: Vec::new(),
            use_closed_form: true,
            reach_bounds: Vec::new(),
            use_reach_bound: true,
            skip_table_if_singular: true,
            #[cfg(test)]
            settled_at_singularity: 0,
            branches_when_seed_fails: true,
            refine_seed_branch: false,
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
            nearest_asked: 0,
            ws: Workspace::new(calibrated),
            best_normal: nalgebra::Matrix6::zeros(),
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

    /// Forward kinematics of the calibrated model the solver has evaluated so far (not those
    /// of the table of starts, built once per target frame): the search's cost, deterministic
    /// where CPU times are not.
    pub fn evaluations(&self) -> u64 {
        self.comp.evaluations()
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
        self.seeded = seed.is_some();
        // On a tree, with a seed, the joints shared with another branch's tool stay at the
        // seed (the other arms keep their poses: a posture's rows agree on them).
        self.comp.held = match seed {
            Some(_) => super::shared_joints(self.robot, target),
            None => 0,
        };
        let closed_form = matches!(goal, Goal::Pose(_)) && self.has_closed_form(target);
        let out_of_reach = match goal {
            Goal::Pose(frame) => self.out_of_reach(frame, target),
            Goal::Position(_) => false,
        };
        // Step 1: the reference, when it is one. The table's nearest starts are looked up only
        // when needed: a seed that converges needs none.
        let (from_reference, mut looked_up) =
            self.choose_reference(goal, target, seed, closed_form);
        let mut best: Option<(Rank, Solved)> = None;
        if from_reference {
            let rank = self.attempt_from_reference(goal, target, seed.is_some(), &mut best, out);
            if usable(&rank) {
                return self.finish(best.expect("considered").1, goal, out);
            }
        }
        if out_of_reach {
            return self.answer_out_of_reach(goal, target, seed, looked_up, best, out);
        }
        // Step 1b: the nominal robot's closed-form branches; with a seed, unless the seed's own
        // solution was reached at a singularity (the goal lies at one, where the branches do
        // not settle it and the table's first start does).
        let seed_rank = best.as_ref().map(|(r, _)| *r);
        let seed_singular = seed_rank.is_some_and(|r| !r.0[0] && r.0[4]);
        let seed_failed = seed_rank.is_some_and(|r| r.0[0]);
        let branches_tried =
            closed_form && !seed_singular && (!seed_failed || self.branches_when_seed_fails);
        // Whether the branches were every solution of the arm they solve (the nominal robot
        // for the families, the calibrated one for the general form; `Branches::complete`).
        let mut complete = false;
        if branches_tried {
            let answer;
            (answer, complete) =
                self.try_closed_form(goal, target, seed, &mut best, &mut looked_up, out);
            if let Some(solved) = answer {
                return solved;
            }
        }
        if !looked_up {
            self.find_nearest(goal, target);
        }
        // The search is settled (see [`settled`]) judged on the attempts before the table's and
        // the table's own, except, with a seed its own attempt did not reach, the closed form's
        // branches: the table's starts then look for the seed's solution as they would without
        // the branches (a stall of the seed's attempt near a singularity, and of the branch
        // nearest it, can hide a solution the table's nearest starts find).
        let mut judged = if seed_failed && branches_tried {
            seed_rank
        } else {
            best.as_ref().map(|(r, _)| *r)
        };
        // Step 2: the nearest starts of the table.
        let (any_usable, tried) =
            self.try_nearest_starts(goal, target, seed, &mut best, &mut judged, out);
        // Step 3: nothing usable near the goal: starts spread over the whole table, unless the
        // search is settled (with a seed; without one, after the closed form's branches too).
        let settled_now = settled(&judged, tried, seed.is_some())
            && (seed.is_some() || (complete && self.skip_table_if_singular));
        if !any_usable && !settled_now {
            self.try_spread_starts(goal, target, seed, &mut best, &mut judged, tried, out);
        }
        self.polish(best.expect("at least one attempt"), goal, target, out)
    }

    /// Step 1: sets the reference: the seed given, else the previous goal's solution, else the
    /// middle of the reading ranges. Returns whether the search starts from it (the seed;
    /// without one, the previous solution when no closed form's branches come first and it
    /// lies nearer the goal than any start of the table), and whether the table's nearest
    /// starts were looked up into `self.nearest` to tell.
    fn choose_reference(
        &mut self,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        closed_form: bool,
    ) -> (bool, bool) {
        match (seed, &self.previous) {
            (Some(s), _) => {
                self.reference.copy_from_slice(s);
                (true, false)
            }
            (None, Some(p)) if closed_form => {
                // The branch nearest the previous solution is among the closed form's.
                self.reference.copy_from_slice(p);
                (false, false)
            }
            (None, Some(p)) => {
                self.reference.copy_from_slice(p);
                self.reference_is_nearest(goal, target)
            }
            (None, None) => {
                self.reference.copy_from_slice(&self.middle);
                (false, false)
            }
        }
    }

    /// One attempt from the reference, with the full iteration cap and (for a redundant arm)
    /// the solution nearest it; its rank (its solution kept in `out` when it ranks before
    /// `best`, judged with a seed when `seeded`).
    fn attempt_from_reference(
        &mut self,
        goal: &Goal,
        target: Target,
        seeded: bool,
        best: &mut Option<(Rank, Solved)>,
        out: &mut [f64],
    ) -> Rank {
        let mut start = std::mem::take(&mut self.start);
        start.copy_from_slice(&self.reference);
        let s = self.attempt(goal, target, &start, true);
        self.start = start;
        self.consider(s, seeded, best, out)
    }

    /// The answer for a goal the reach bound proves out of reach (`best`: the reference's
    /// attempt, if one was made): a single attempt, polished ([`Self::polish`]).
    fn answer_out_of_reach(
        &mut self,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        looked_up: bool,
        mut best: Option<(Rank, Solved)>,
        out: &mut [f64],
    ) -> Solved {
        // No start can reach the goal: the reference's attempt, else the nearest start's,
        // is the answer.
        if best.is_none() {
            if !looked_up {
                self.find_nearest(goal, target);
            }
            match self.nearest.first() {
                Some(&(_, i)) => {
                    self.attempt_start(i as usize, goal, target, seed, &mut best, out);
                }
                None => {
                    self.attempt_from_reference(goal, target, seed.is_some(), &mut best, out);
                }
            }
        }
        self.polish(best.expect("an attempt"), goal, target, out)
    }

    /// Step 1b: the closed form's branches ([`Self::closed_form_branches`]), then, without a
    /// seed, the previous solution when it lies nearer the goal than any start of the table.
    /// The answer when they end the search: a usable solution, every solution of the goal
    /// known, or, with a seed, a goal out of the calibrated robot's reach; `None` when the
    /// table's starts are to be tried (`looked_up` set when their nearest were looked up).
    /// With whether the branches were every solution of the arm they solve.
    fn try_closed_form(
        &mut self,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        best: &mut Option<(Rank, Solved)>,
        looked_up: &mut bool,
        out: &mut [f64],
    ) -> (Option<Solved>, bool) {
        let (settled, exact, complete) = self.closed_form_branches(goal, target, best, out);
        if settled {
            let solved = self.finish(best.take().expect("a branch was tried").1, goal, out);
            return (Some(solved), complete);
        }
        // With a seed, no solution reached from it nor from any branch, among them branches
        // the nominal robot reaches exactly: the calibrated robot's solutions lie near those
        // (the two models differ by a calibration), so the goal is out of its reach (the
        // table's starts found no solution for any such goal of the compensate bench).
        if seed.is_some() && best.as_ref().is_some_and(|(r, _)| r.0[0]) && exact > 0 && complete {
            let attempt = best.take().expect("at least one attempt");
            return (Some(self.polish(attempt, goal, target, out)), complete);
        }
        if let (None, Some(p)) = (seed, &self.previous) {
            // Not settled: the previous solution as a start too, as for any robot.
            self.reference.copy_from_slice(p);
            let (nearest, looked) = self.reference_is_nearest(goal, target);
            *looked_up |= looked;
            if nearest && usable(&self.attempt_from_reference(goal, target, false, best, out)) {
                let solved = self.finish(best.take().expect("considered").1, goal, out);
                return (Some(solved), complete);
            }
        }
        (None, complete)
    }

    /// Step 2: attempts from the table's starts nearest the goal, nearest first (looked up
    /// further as needed), until one is usable (without a seed) or the search is [`settled`],
    /// each ranked into `judged`. Returns whether one was usable, and how many were tried.
    fn try_nearest_starts(
        &mut self,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        best: &mut Option<(Rank, Solved)>,
        judged: &mut Option<Rank>,
        out: &mut [f64],
    ) -> (bool, usize) {
        let mut any_usable = false;
        let mut tried = 0;
        for k in 0.. {
            if k == self.nearest.len() && !self.more_nearest(goal, target) {
                break;
            }
            let i = self.nearest[k].1 as usize;
            let rank = self.attempt_start(i, goal, target, seed, best, out);
            any_usable |= usable(&rank);
            lower(judged, rank);
            tried += 1;
            if any_usable && seed.is_none() {
                break;
            }
            if settled(judged, tried, seed.is_some()) {
                break;
            }
        }
        (any_usable, tried)
    }

    /// Step 3: attempts from [`Self::SPREAD`] starts spread evenly over the table (with a
    /// seed, the first [`Self::SEEDED_SPREAD`] of them), each ranked into `judged`, until one
    /// is usable (without a seed) or, with a seed, the search is [`settled`] (`tried` nearest
    /// starts having been tried before).
    #[allow(clippy::too_many_arguments)]
    fn try_spread_starts(
        &mut self,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        best: &mut Option<(Rank, Solved)>,
        judged: &mut Option<Rank>,
        tried: usize,
        out: &mut [f64],
    ) {
        let rows = self.starts.len() / self.robot.dof();
        if rows == 0 {
            return;
        }
        let mut any_usable = false;
        for k in 0..Self::SPREAD {
            if seed.is_some() && k >= Self::SEEDED_SPREAD {
                break;
            }
            let i = (k * rows / Self::SPREAD + rows / (2 * Self::SPREAD)) % rows;
            let rank = self.attempt_start(i, goal, target, seed, best, out);
            any_usable |= usable(&rank);
            lower(judged, rank);
            if (any_usable && seed.is_none())
                || (seed.is_some() && settled(judged, tried, seed.is_some()))
            {
                break;
            }
        }
    }

    /// The best attempt `(rank, solved)`, its readings in `out`, finished (the next goal's
    /// reference): when it did not reach the goal, first run again from where it stopped
    /// with the full iteration cap.
    fn polish(
        &mut self,
        (rank, mut solved): (Rank, Solved),
        goal: &Goal,
        target: Target,
        out: &mut [f64],
    ) -> Solved {
        if rank.0[0] {
            // Nothing reached within the search's iteration cap: the best attempt gets the
            // full cap (near a singularity the solver converges slowly).
            let mut start = std::mem::take(&mut self.start);
            start.copy_from_slice(out);
            let s = self.attempt(goal, target, &start, false);
            self.start = start;
            // The damped least squares never increases the error: the polished one is better.
            out.copy_from_slice(&self.candidate);
            self.best_normal = self.comp.judged_normal;
            solved = s;
        }
        self.finish(solved, goal, out)
    }

    /// Whether the nominal robot has a closed form for `target` (worked out once per target).
    fn has_closed_form(&mut self, target: Target) -> bool {
        if !self.use_closed_form {
            return false;
        }
        if let Some((_, a)) = self.closed_forms.iter().find(|(t, _)| *t == target) {
            return a.is_some();
        }
        let a = match Analytic::new(self.nominal, target) {
            Some(a) if a.family() != Family::General => Some(a),
            // The general form needs no special geometry: the calibrated robot's own, whose
            // branches are its exact solutions (of its rigid geometry).
            Some(_) => Analytic::new(self.robot, target),
            None => None,
        };
        let found = a.is_some();
        self.closed_forms.push((target, a));
        found
    }

    /// Whether the calibrated arm's reach bound proves that no posture puts `target` at
    /// `goal` (the bound worked out once per target).
    fn out_of_reach(&mut self, goal: &crate::model::kinematics::Frame, target: Target) -> bool {
        if !self.use_reach_bound {
            return false;
        }
        if !self.reach_bounds.iter().any(|(t, _)| *t == target) {
            let b = ReachBound::new(
                self.robot,
                target,
                self.options.position_tolerance,
                self.options.attitude_tolerance,
            );
            self.reach_bounds.push((target, b));
        }
        let (_, bound) = self
            .reach_bounds
            .iter()
            .find(|(t, _)| *t == target)
            .expect("worked out");
        bound.as_ref().is_some_and(|b| b.out_of_reach(goal))
    }

    /// The search without the reach bound: every goal searched.
    #[cfg(test)]
    pub(crate) fn without_reach_bound(mut self) -> Self {
        self.use_reach_bound = false;
        self
    }

    /// The search with a goal at a singularity still tried from the table's starts: the
    /// nearest, and unseeded, the spread ones.
    #[cfg(test)]
    pub(crate) fn with_table_if_singular(mut self) -> Self {
        self.skip_table_if_singular = false;
        self
    }

    /// The search with a seeded goal that its seed does not reach tried from the table's starts
    /// alone, as before the closed form's branches were tried for it.
    #[cfg(test)]
    pub(crate) fn without_branches_when_seed_fails(mut self) -> Self {
        self.branches_when_seed_fails = false;
        self
    }

    /// The search with the closed form's branch at the seed refined again, as before the
    /// seed's own attempt stood for it.
    #[cfg(test)]
    pub(crate) fn with_seed_branch_refined(mut self) -> Self {
        self.refine_seed_branch = true;
        self
    }

    /// The search without the closed form: the table of starts for every goal.
    #[cfg(test)]
    pub(crate) fn without_closed_form(mut self) -> Self {
        self.use_closed_form = false;
        self
    }

    /// The search with every attempt run to its iteration cap, stalled or not (as before the
    /// stall exit).
    #[cfg(test)]
    pub(crate) fn without_stall_exit(mut self) -> Self {
        self.comp.stall_exit = false;
        self
    }

    /// The search with every attempt's conditioning worked out from its eigenvalues, as before
    /// bounds settled the singular flag.
    #[cfg(test)]
    pub(crate) fn without_deferred_conditioning(mut self) -> Self {
        self.comp.defer_conditioning = false;
        self
    }

    /// The search with the forward kinematics at every attempt's solution evaluated anew, as
    /// before the solver's last one was reused.
    #[cfg(test)]
    pub(crate) fn without_last_forward_reused(mut self) -> Self {
        self.comp.reuse_last_forward = false;
        self
    }

    /// Step 1b: the nominal robot's closed-form branches as starts, each refined on the
    /// calibrated model within the search's iteration cap, in the order: branches the nominal
    /// robot reaches before those it does not, then by what the branch itself predicts
    /// (outside a range, not in the configuration, turned from the seed beyond
    /// [`Options::branch`]), then nearest the reference first. Stops at the first usable
    /// solution. Whether the search is settled: a usable solution found, or the branches
    /// complete (see `Branches::complete`; with a seed, branches not complete are not tried),
    /// every branch the nominal robot reaches refined to a reached solution of its own, none
    /// two to the same, and the best of them in the configuration and away from
    /// singularities, flagged only for a joint range or a change from the seed (the goal's
    /// solutions are then all known; near a singularity the calibrated robot may have
    /// solutions the nominal one has not, which the table of starts looks for). Without a
    /// seed, the general form's branches of an arm without an elastic model are the
    /// calibrated arm's own, all of them: a best at a singularity settles it too. Returns
    /// whether it is settled, how many branches the nominal robot reaches exactly, and
    /// whether they were complete. (For the general form, "the nominal robot" is the
    /// calibrated one it solves.)
    fn closed_form_branches(
        &mut self,
        goal: &Goal,
        target: Target,
        best: &mut Option<(Rank, Solved)>,
        out: &mut [f64],
    ) -> (bool, usize, bool) {
        let Goal::Pose(frame) = goal else {
            return (false, 0, false);
        };
        let Some(analytic) = self
            .closed_forms
            .iter()
            .find(|(t, _)| *t == target)
            .and_then(|(_, a)| a.as_ref())
        else {
            return (false, 0, false);
        };
        let branches = analytic.solve(frame);
        let complete = branches.complete();
        let every_solution = self.skip_table_if_singular
            && !self.seeded
            && analytic.family() == Family::General
            && self.robot.elastic.is_none();
        // With a seed, branches that may not be all the goal's solutions are not tried: they
        // seldom lie within a change of configuration of a seed that failed, and the table's
        // starts near the seed look for its solution.
        if self.seeded && !complete {
            return (false, 0, false);
        }
        let branches = branches.as_slice();
        let exact = branches.iter().filter(|b| b.exact).count();
        // ((inexact, outside a range, not in the configuration, turned), squared distance to
        // the reference), readings.
        type Key = ([bool; 4], f64);
        let mut keyed: [(Key, [f64; 6]); MOST] = [(([false; 4], 0.0), [0.0; 6]); MOST];
        let keyed = &mut keyed[..branches.len()];
        for (k, b) in keyed.iter_mut().zip(branches) {
            let mut v = b.readings;
            let outside = self.place_turns(&mut v) != 0;
            let turned = self.seeded && self.turned_from_reference(&v);
            let elsewhere = self.classifier.as_ref().is_some_and(|c| {
                self.comp.calibrated.forward(&v, &mut self.ws);
                !c.matches(self.robot, &v, &self.ws)
            });
            let distance = v
                .iter()
                .zip(&self.reference)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>();
            *k = (([!b.exact, outside, elsewhere, turned], distance), v);
        }
        keyed.sort_by(|a, b| a.0 .0.cmp(&b.0 .0).then(a.0 .1.total_cmp(&b.0 .1)));
        let seeded = self.seeded;
        let same = |u: &[f64], v: &[f64]| u.iter().zip(v).all(|(a, b)| (a - b).abs() < 1e-9);
        // With a seed, its own attempt came first (the only one so far): whether it reached
        // the goal, and where.
        let mut from_seed = [0.0; 6];
        let seed_reached = match best {
            Some((rank, _)) if seeded && !self.refine_seed_branch => {
                from_seed.copy_from_slice(out);
                Some(!rank.0[0])
            }
            _ => None,
        };
        // The solutions the branches the nominal robot reaches refined to.
        let mut found = [[0.0; 6]; MOST];
        let mut exact_reached = 0;
        let mut exact_failed = false;
        for (i, ((predicted, _), v)) in keyed.iter().enumerate() {
            // The same solution twice (a singular goal): refined once.
            if keyed[..i].iter().any(|(_, u)| same(u, v)) {
                continue;
            }
            // The seed itself (a program's readings are the nominal robot's exact solution of
            // the pose it means): refined already, from the seed, with the full iteration cap.
            if let Some(reached) = seed_reached.filter(|_| same(v, &self.reference)) {
                if !predicted[0] {
                    if reached {
                        found[exact_reached] = from_seed;
                        exact_reached += 1;
                    } else {
                        exact_failed = true;
                    }
                }
                continue;
            }
            let s = self.attempt_capped(goal, target, v);
            if !predicted[0] {
                if s.flags.unreachable {
                    exact_failed = true;
                } else {
                    found[exact_reached].copy_from_slice(&self.candidate);
                    exact_reached += 1;
                }
            }
            if usable(&self.consider(s, seeded, best, out)) {
                return (true, exact, complete);
            }
        }
        // Two branches refined to one solution: near a singularity the calibrated robot's
        // solutions moved from the nominal's, and one was missed.
        let merged = (1..exact_reached).any(|i| {
            found[..i]
                .iter()
                .any(|u| u.iter().zip(&found[i]).all(|(a, b)| (a - b).abs() < 1e-6))
        });
        // Outside a range or turned from the seed is the goal's; not in the configuration or
        // near a singularity, the solutions may be where the nominal robot has none. The
        // general form's complete branches of a rigid arm are every solution of the arm
        // searched, near a singularity too: unseeded, a singular best is the goal's (the
        // table's starts converge to those solutions, or stall).
        let placed = best
            .as_ref()
            .is_some_and(|(r, _)| !r.0[0] && !r.0[2] && (!r.0[4] || every_solution));
        let settled = complete && placed && exact_reached > 0 && !exact_failed && !merged;
        #[cfg(test)]
        {
            self.settled_at_singularity +=
                (settled && best.as_ref().is_some_and(|(r, _)| r.0[4])) as usize;
        }
        (settled, exact, complete)
    }

    /// One attempt from start `i` of the table, within the search's iteration cap; its rank
    /// (its solution kept in `out` when it ranks before `best`).
    fn attempt_start(
        &mut self,
        i: usize,
        goal: &Goal,
        target: Target,
        seed: Option<&[f64]>,
        best: &mut Option<(Rank, Solved)>,
        out: &mut [f64],
    ) -> Rank {
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

    /// Keeps the candidate in `out` (and its normal matrix) when it ranks before `best`; its
    /// rank.
    fn consider(
        &mut self,
        solved: Solved,
        seeded: bool,
        best: &mut Option<(Rank, Solved)>,
        out: &mut [f64],
    ) -> Rank {
        let rank = self.rank(&solved, seeded);
        if best.as_ref().is_none_or(|(b, _)| rank < *b) {
            out.copy_from_slice(&self.candidate);
            self.best_normal = self.comp.judged_normal;
            *best = Some((rank, solved));
        }
        rank
    }

    /// The answer `solved` at `out`, its conditioning worked out when its judgement deferred
    /// it (from the normal matrix kept with it); a reached goal's solution is recorded as the
    /// next reference.
    fn finish(&mut self, mut solved: Solved, goal: &Goal, out: &[f64]) -> Solved {
        if solved.conditioning.is_nan() {
            let rows = match goal {
                Goal::Pose(_) => 6,
                Goal::Position(_) => 3,
            };
            solved.conditioning = self.comp.conditioning_of(&self.best_normal, rows);
        }
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
        // at the reference (the seed, the previous row's solution, or mid-range); so do the
        // joints held at the seed.
        let mut from = std::mem::take(&mut self.from);
        from.copy_from_slice(start);
        if self.robot.is_tree() {
            let attach = crate::model::kinematics::target_joint(self.robot, target);
            for (j, v) in from.iter_mut().enumerate() {
                if !self.robot.joint_moves(j, attach) || self.comp.held & (1 << j) != 0 {
                    *v = self.reference[j];
                }
            }
        }
        let mut s = self
            .comp
            .local(goal, target, &from, nearest, &mut candidate);
        self.from = from;
        s.flags.out_of_range |= self.place_turns(&mut candidate);
        if self.seeded {
            // A change of configuration from the seed given (the reference).
            s.flags.branch |= self.turned_from_reference(&candidate);
        }
        if let Some(c) = &self.classifier {
            // The geometry does not change with whole turns: the solver's last forward
            // kinematics is the solution's.
            s.flags.configuration = !c.matches(self.robot, &candidate, &self.comp.ws);
        }
        self.candidate = candidate;
        s
    }

    /// Moves the revolute readings of `v` by whole turns to the turn nearest the reference,
    /// then into the joint's range when that turn is outside it (see the module's
    /// documentation); the joints (bit `j` for joint `j + 1`) then outside their range.
    fn place_turns(&self, v: &mut [f64]) -> u64 {
        let mut outside = 0;
        for (j, joint) in self.robot.joints.iter().enumerate() {
            let v = &mut v[j];
            if let Some(t) = self.turn[j] {
                let range = joint
                    .range
                    .unwrap_or((self.middle[j] - 0.5 * t, self.middle[j] + 0.5 * t));
                *v = super::place_turn(*v, t, self.reference[j], range);
            }
            if let Some((lo, hi)) = joint.range {
                if *v < lo || *v > hi {
                    outside |= 1 << j;
                }
            }
        }
        outside
    }

    /// Whether a revolute joint of `v` turned more than [`Options::branch`] (rad) from the
    /// reference: a change of configuration from the seed.
    fn turned_from_reference(&self, v: &[f64]) -> bool {
        self.robot.joints.iter().enumerate().any(|(j, joint)| {
            joint.kind == JointKind::Revolute
                && (joint.value(v, j) - joint.value(&self.reference, j)).abs() > self.options.branch
        })
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
        (flag_rank(f), distance)
    }

    /// Builds the table of start frames for `target` (once).
    fn ensure_table(&mut self, target: Target) {
        if self.tables.iter().any(|(t, _)| *t == target) {
            return;
        }
        let dof = self.robot.dof();
        let starts = std::mem::take(&mut self.starts);
        let keys: Vec<[f64; 12]> = starts
            .chunks_exact(dof)
            .map(|r| self.frame_key(r, target))
            .collect();
        self.starts = starts;
        self.tables
            .push((target, StartTable::new(&keys, self.comp.reach)));
    }

    /// Fills `self.nearest` with the [`Self::FIRST_NEAREST`] starts nearest `goal`, nearest
    /// first (ties by start index): most goals need no more (see [`Self::more_nearest`]).
    fn find_nearest(&mut self, goal: &Goal, target: Target) {
        let keep = Self::FIRST_NEAREST.min(self.most_nearest());
        self.look_up_nearest(goal, target, keep);
    }

    /// Extends `self.nearest` to the [`Self::ATTEMPTS`] starts nearest `goal` (for a seeded
    /// goal [`Self::SEEDED_ATTEMPTS`]), the ones it holds first, in the same order (the same
    /// lookup, keeping more); whether it now holds more.
    fn more_nearest(&mut self, goal: &Goal, target: Target) -> bool {
        let (held, most) = (self.nearest.len(), self.most_nearest());
        // Fewer held than asked for: the table has no more.
        if held < self.nearest_asked || held >= most {
            return false;
        }
        self.look_up_nearest(goal, target, most);
        self.nearest.len() > held
    }

    /// How many of the nearest starts a goal tries at most: a seeded goal only a few.
    fn most_nearest(&self) -> usize {
        if self.seeded {
            Self::SEEDED_ATTEMPTS
        } else {
            Self::ATTEMPTS
        }
    }

    /// The table of starts' frames for `target` (built when first asked for).
    fn table(&mut self, target: Target) -> &StartTable {
        self.ensure_table(target);
        &self
            .tables
            .iter()
            .find(|(t, _)| *t == target)
            .expect("built")
            .1
    }

    /// Fills `self.nearest` with the `keep` starts nearest `goal`, nearest first (ties by
    /// start index).
    fn look_up_nearest(&mut self, goal: &Goal, target: Target, keep: usize) {
        let reach2 = self.comp.reach * self.comp.reach;
        let mut nearest = std::mem::take(&mut self.nearest);
        self.table(target).nearest(goal, reach2, keep, &mut nearest);
        self.nearest = nearest;
        self.nearest_asked = keep;
    }

    /// Whether the reference (the previous solution) lies at least as near `goal` as every
    /// start of the table (the search then starts there), and whether the table's nearest
    /// starts were looked up into `self.nearest` to tell: for a pose goal only when some start
    /// lies nearer (most goals of a path lie near the previous one).
    fn reference_is_nearest(&mut self, goal: &Goal, target: Target) -> (bool, bool) {
        let reference = std::mem::take(&mut self.reference);
        let d = self.distance_of(goal, target, &reference);
        self.reference = reference;
        if matches!(goal, Goal::Pose(_)) && d.is_finite() {
            let reach2 = self.comp.reach * self.comp.reach;
            if !self.table(target).pose_nearer(goal, reach2, d) {
                return (true, false);
            }
        }
        self.find_nearest(goal, target);
        (
            self.nearest.first().is_none_or(|&(best, _)| d <= best),
            true,
        )
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

#[cfg(test)]
mod tests {
    use super::super::analytic::{tests::random_arm, Family};
    use super::*;
    use crate::apps::simulate::{perturb, reading_range, sample_postures, PerturbStd};
    use crate::model::kinematics::Chain;
    use nalgebra::Vector3;

    /// A nominal arm with its ranges set (+-150 deg: one turn of each joint in range) and its
    /// calibrated twin (1 mm, 0.3 deg).
    fn twin(mut nominal: Robot, seed: u64) -> (Robot, Robot) {
        for j in 0..nominal.dof() {
            nominal.joints[j].range = Some(reading_range(&nominal, j));
        }
        let std = PerturbStd {
            length: 1e-3,
            angle: 0.3f64.to_radians(),
            slope_fraction: 0.002,
        };
        let calibrated = perturb(&nominal, std, seed);
        (nominal, calibrated)
    }

    /// Solves `goals` (with their seeds) with the closed form's branches and with the search of
    /// the table alone: the rows flagged each way, the largest difference of readings where
    /// both are usable and converged below 1e-10 (the table's starts stop at
    /// [`TargetSearch::CAP`] iterations, some within the tolerances but not below that), and the rows whose flags rank worse with the closed form (unreachable,
    /// outside a range, not in the configuration, a change of configuration, singular).
    fn both_ways(
        nominal: &Robot,
        calibrated: &Robot,
        goals: &[(Goal, Option<Vec<f64>>)],
        configuration: Option<Configuration>,
    ) -> (usize, usize, f64, usize) {
        let make = |closed: bool| {
            let s = TargetSearch::new(calibrated, nominal, Options::default()).unwrap();
            let s = if closed { s } else { s.without_closed_form() };
            match &configuration {
                Some(c) => s.with_configuration(c.clone()).unwrap(),
                None => s,
            }
        };
        let (mut closed, mut plain) = (make(true), make(false));
        let (mut a, mut b) = (vec![0.0; 6], vec![0.0; 6]);
        let (mut flagged_closed, mut flagged_plain, mut largest, mut worse) = (0, 0, 0.0f64, 0);
        for (goal, seed) in goals {
            let sa = closed.solve(goal, Target::EndEffector, seed.as_deref(), &mut a);
            let sb = plain.solve(goal, Target::EndEffector, seed.as_deref(), &mut b);
            flagged_closed += sa.flags.any() as usize;
            flagged_plain += sb.flags.any() as usize;
            worse += (flag_rank(&sa.flags) > flag_rank(&sb.flags)) as usize;
            let converged =
                |s: &Solved| s.position_error < 1e-10 && s.attitude_error.is_none_or(|a| a < 1e-10);
            if !sa.flags.any() && !sb.flags.any() && converged(&sa) && converged(&sb) {
                for (x, y) in a.iter().zip(&b) {
                    largest = largest.max((x - y).abs());
                }
            }
        }
        (flagged_closed, flagged_plain, largest, worse)
    }

    fn poses(robot: &Robot, postures: &[Vec<f64>]) -> Vec<crate::model::kinematics::Frame> {
        let chain = Chain::new(robot);
        postures
            .iter()
            .map(|p| chain.frame_at(p, Target::EndEffector))
            .collect()
    }

    /// Goals, each with the readings that seed it (if any).
    type Goals = Vec<(Goal, Option<Vec<f64>>)>;

    /// The poses `robot` reaches at `postures` as unseeded pose goals, then their positions
    /// as unseeded position goals.
    fn unseeded_pose_and_position_goals(robot: &Robot, postures: &[Vec<f64>]) -> Goals {
        let reached = poses(robot, postures);
        reached
            .iter()
            .map(|f| (Goal::Pose(*f), None))
            .chain(
                reached
                    .iter()
                    .map(|f| (Goal::Position(f.translation), None)),
            )
            .collect()
    }

    /// `count` postures of `nominal` drawn with `seed` (their readings), and the poses they
    /// reach as seeded targets (each seeded by its own readings).
    fn seeded_targets(nominal: &Robot, count: usize, seed: u64) -> (Vec<Vec<f64>>, Goals) {
        let postures: Vec<Vec<f64>> = sample_postures(nominal, count, seed)
            .into_iter()
            .map(|p| p.readings)
            .collect();
        let seeded = poses(nominal, &postures)
            .into_iter()
            .zip(&postures)
            .map(|(f, p)| (Goal::Pose(f), Some(p.clone())))
            .collect();
        (postures, seeded)
    }

    /// Seeded targets (the poses programs of the nominal arm mean, seeded by their readings):
    /// the closed form's branches give what the search of the table gives where both find a
    /// usable solution (to 1e-9 in readings; both converge far below it). Seeded targets and
    /// unseeded ones in a named configuration: no row is flagged worse than by the search of
    /// the table, and at most 3 of 300 better (the search is not exhaustive). (Unseeded
    /// solutions may differ: with random joint offsets, several branches can be in one named
    /// configuration, and each way takes the first usable one it finds.)
    fn agrees_with_the_search(family: Family) {
        for seed in [3, 8] {
            let (nominal, calibrated) = twin(random_arm(family, seed), seed + 50);
            assert!(Analytic::new(&nominal, Target::EndEffector).is_some());
            let (postures, seeded) = seeded_targets(&nominal, 300, seed);
            let (c, p, d, w) = both_ways(&nominal, &calibrated, &seeded, None);
            assert_eq!(
                w, 0,
                "{family:?} seed {seed}: seeded rows flagged worse ({c}, {p})"
            );
            assert!(
                c <= p && p <= c + 3,
                "{family:?} seed {seed}: flagged {c}, {p}"
            );
            assert!(
                d < 1e-9,
                "{family:?} seed {seed}: seeded solutions {d} apart"
            );
            let unseeded: Vec<(Goal, Option<Vec<f64>>)> = poses(&calibrated, &postures)
                .into_iter()
                .map(|f| (Goal::Pose(f), None))
                .collect();
            let arm = Configuration::parse("shoulder=front,elbow=up,wrist=noflip").unwrap();
            let (c, p, _, w) = both_ways(&nominal, &calibrated, &unseeded, Some(arm));
            assert_eq!(
                w, 0,
                "{family:?} seed {seed}: unseeded rows flagged worse ({c}, {p})"
            );
            assert!(
                c <= p && p <= c + 3,
                "{family:?} seed {seed}: flagged {c}, {p}"
            );
        }
    }

    #[test]
    fn general_closed_form_agrees_with_the_search() {
        agrees_with_the_search(Family::General);
    }

    #[test]
    fn ur_type_closed_form_agrees_with_the_search() {
        agrees_with_the_search(Family::UrType);
    }

    #[test]
    fn spherical_wrist_closed_form_agrees_with_the_search() {
        agrees_with_the_search(Family::SphericalWrist);
    }

    /// Solves `goals` with and without the stall exit (every attempt run to its cap): each
    /// row's flags ranked (see `both_ways`), its readings, whether converged below 1e-10, and
    /// the forward kinematics evaluated, per way.
    #[allow(clippy::type_complexity)]
    fn with_and_without_stall_exit(
        nominal: &Robot,
        calibrated: &Robot,
        goals: &[(Goal, Option<Vec<f64>>)],
        closed_form: bool,
    ) -> [(Vec<([bool; 5], Vec<f64>, bool)>, u64); 2] {
        [true, false].map(|exit| {
            let s = TargetSearch::new(calibrated, nominal, Options::default()).unwrap();
            let s = if closed_form {
                s
            } else {
                s.without_closed_form()
            };
            let mut s = if exit { s } else { s.without_stall_exit() };
            let mut out = vec![0.0; 6];
            let rows = goals
                .iter()
                .map(|(g, seed)| {
                    let r = s.solve(g, Target::EndEffector, seed.as_deref(), &mut out);
                    let f = r.flags;
                    let converged =
                        r.position_error < 1e-10 && r.attitude_error.is_none_or(|a| a < 1e-10);
                    (flag_rank(&f), out.clone(), converged)
                })
                .collect();
            (rows, s.evaluations())
        })
    }

    /// The stall exit (an attempt stuck at a local minimum of the error ends there, instead of
    /// running to its cap) changes no answer and saves work: on a random arm (its closed form
    /// turned off: the search of the table alone, as for an arm with none) and a
    /// spherical-wrist arm, over seeded pose targets (the nominal poses of programs, some
    /// of whose seeds fail) and unseeded pose and position targets, every row is usable or not
    /// as without it, usable rows converged both ways agree to 1e-9 in readings (both converge
    /// far below it: a stalled attempt is never the one taken), and fewer forward kinematics
    /// are evaluated (measured: 0.62 and 0.78 of them on the random arm, seeded and unseeded;
    /// 0.59 and 0.95 on the wrist arm, whose unseeded goals seldom stall; the bounds leave a
    /// margin, and an unchanged solver gives 1).
    #[test]
    fn stalled_attempts_end_early_and_change_no_answer() {
        let arms = [
            (
                crate::apps::simulate::random_robot(&[JointKind::Revolute; 6], 21),
                0.7,
                0.85,
                false,
            ),
            (random_arm(Family::SphericalWrist, 8), 0.7, 0.98, true),
        ];
        for (arm, (nominal, seeded_fall, unseeded_fall, closed_form)) in
            arms.into_iter().enumerate()
        {
            let (nominal, calibrated) = twin(nominal, 22);
            let (postures, seeded) = seeded_targets(&nominal, 200, 5);
            let unseeded = unseeded_pose_and_position_goals(&calibrated, &postures);
            for (kind, goals, fall) in [
                ("seeded", &seeded, seeded_fall),
                ("unseeded", &unseeded, unseeded_fall),
            ] {
                let [(new, cost_new), (old, cost_old)] =
                    with_and_without_stall_exit(&nominal, &calibrated, goals, closed_form);
                let mut flagged = 0;
                for (k, (a, b)) in new.iter().zip(&old).enumerate() {
                    let usable = |r: &[bool; 5]| *r == [false; 5];
                    assert_eq!(usable(&a.0), usable(&b.0), "arm {arm} {kind} row {k}");
                    flagged += !usable(&a.0) as usize;
                    if usable(&a.0) && a.2 && b.2 {
                        let d = a.1.iter().zip(&b.1).map(|(x, y)| (x - y).abs());
                        let d = d.fold(0.0, f64::max);
                        assert!(d < 1e-9, "arm {arm} {kind} row {k}: {d}");
                    }
                }
                assert!(
                    (cost_new as f64) < fall * cost_old as f64,
                    "arm {arm} {kind}: {cost_new} against {cost_old} forward kinematics \
                     ({flagged} rows flagged)"
                );
            }
        }
    }

    /// The closed form's branch at the seed (a program's readings are the nominal robot's exact
    /// solution of the pose they mean) is not refined again, the seed's own attempt standing
    /// for it: on a spherical-wrist arm and the IRB 120, over seeded pose targets, every row
    /// keeps its flags, the usable ones their readings to 1e-9 (both converge far below it),
    /// and fewer forward kinematics are evaluated (measured: 0.96 of them on the IRB 120's
    /// 1,000 targets of the compensate bench; an unchanged search gives 1).
    #[test]
    fn the_seed_branch_is_not_refined_again() {
        for (arm, nominal, calibrated) in reach_test_arms().into_iter().take(2) {
            let (_, seeded) = seeded_targets(&nominal, 300, 5);
            let [(new, cost_new), (old, cost_old)] = [false, true].map(|again| {
                let s = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
                let mut s = if again {
                    s.with_seed_branch_refined()
                } else {
                    s
                };
                let mut out = vec![0.0; 6];
                let rows: Vec<_> = seeded
                    .iter()
                    .map(|(g, seed)| {
                        let r = s.solve(g, Target::EndEffector, seed.as_deref(), &mut out);
                        (r.flags, out.clone())
                    })
                    .collect();
                (rows, s.evaluations())
            });
            for (k, (a, b)) in new.iter().zip(&old).enumerate() {
                assert_eq!(a.0, b.0, "arm {arm} row {k}");
                if !a.0.any() {
                    let d = a.1.iter().zip(&b.1).map(|(x, y)| (x - y).abs());
                    let d = d.fold(0.0, f64::max);
                    assert!(d < 1e-9, "arm {arm} row {k}: {d}");
                }
            }
            assert!(
                cost_new < cost_old,
                "arm {arm}: {cost_new} against {cost_old} forward kinematics"
            );
        }
    }

    /// Every row of a search and of the same search changed by `variant`: on a random 6R arm
    /// and the IRB 120 (each with its calibrated twin), over 200 seeded pose targets and the
    /// unseeded pose and position targets of the same postures, `check` is given the arm, the
    /// kind of goals, and each search's rows (result and readings) with its forward kinematics.
    fn compare_with_variant(
        variant: impl Fn(TargetSearch<'_>) -> TargetSearch<'_>,
        check: impl Fn(usize, &str, [(Vec<(Solved, Vec<f64>)>, u64); 2]),
    ) {
        let random = crate::apps::simulate::random_robot(&[JointKind::Revolute; 6], 21);
        let irb120 = reach_test_arms().remove(1).1;
        for (arm, nominal) in [random, irb120].into_iter().enumerate() {
            let (nominal, calibrated) = twin(nominal, 22);
            let (postures, seeded) = seeded_targets(&nominal, 200, 5);
            let unseeded = unseeded_pose_and_position_goals(&calibrated, &postures);
            for (kind, goals) in [("seeded", &seeded), ("unseeded", &unseeded)] {
                let runs = [false, true].map(|changed| {
                    let s = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
                    let mut s = if changed { variant(s) } else { s };
                    let mut out = vec![0.0; 6];
                    let rows: Vec<(Solved, Vec<f64>)> = goals
                        .iter()
                        .map(|(g, seed)| {
                            let r = s.solve(g, Target::EndEffector, seed.as_deref(), &mut out);
                            assert!(r.conditioning.is_finite());
                            (r, out.clone())
                        })
                        .collect();
                    (rows, s.evaluations())
                });
                check(arm, kind, runs);
            }
        }
    }

    /// The solver's last forward kinematics, when evaluated at the solution, serves the flags
    /// there (its Jacobian and conditioning) instead of being evaluated again: on a random 6R
    /// arm and the IRB 120, over seeded pose targets and unseeded pose and position targets,
    /// every row's result (errors, iterations, conditioning, flags) and readings are the same to
    /// the bit, with fewer forward kinematics (measured: 0.95-0.97 of them).
    #[test]
    fn the_last_forward_kinematics_is_reused_at_the_solution() {
        compare_with_variant(
            |s| s.without_last_forward_reused(),
            |arm, kind, [(new, cost_new), (old, cost_old)]| {
                for (k, (a, b)) in new.iter().zip(&old).enumerate() {
                    assert_eq!(a, b, "arm {arm} {kind} row {k}");
                }
                assert!(
                    cost_new < cost_old,
                    "arm {arm} {kind}: {cost_new} against {cost_old} forward kinematics"
                );
            },
        );
    }

    /// Deferring the conditioning of attempts (the singular flag settled by bounds, the
    /// eigenvalues worked out for the answer alone) changes no answer: on a random 6R arm and
    /// the IRB 120, over seeded pose targets and unseeded pose and position targets, every
    /// row's result (errors, iterations, conditioning, flags) and readings are the same to the
    /// bit, with the same forward kinematics; some rows of each are singular.
    #[test]
    fn deferred_conditioning_changes_no_answer() {
        compare_with_variant(
            |s| s.without_deferred_conditioning(),
            |arm, kind, [(deferred, cost_deferred), (eigen, cost_eigen)]| {
                assert_eq!(cost_deferred, cost_eigen, "arm {arm} {kind}");
                for (k, (a, b)) in deferred.iter().zip(&eigen).enumerate() {
                    assert_eq!(a, b, "arm {arm} {kind} row {k}");
                }
                let singular = deferred.iter().filter(|r| r.0.flags.singular).count();
                assert!(singular > 0, "arm {arm} {kind}: no singular row to settle");
            },
        );
    }

    /// The arms the reach bound is tested on, each with its calibrated twin: a random
    /// spherical-wrist arm, the ABB IRB 120 of `examples/robots`, and a random 6R arm (the
    /// general form; its bound is loose).
    fn reach_test_arms() -> Vec<(&'static str, Robot, Robot)> {
        let irb120 = crate::model::robot_file::parse_robot_toml(
            include_str!("../../../../../examples/robots/abb_irb120.toml"),
            "abb_irb120.toml",
        )
        .unwrap();
        let random = crate::apps::simulate::random_robot(&[JointKind::Revolute; 6], 21);
        [
            ("spherical wrist", random_arm(Family::SphericalWrist, 8)),
            ("IRB 120", irb120),
            ("random 6R", random),
        ]
        .into_iter()
        .map(|(name, arm)| {
            let (nominal, calibrated) = twin(arm, 22);
            (name, nominal, calibrated)
        })
        .collect()
    }

    /// The reach bound never refuses a goal the calibrated arm reaches: the poses of 20,000
    /// postures drawn over a whole turn of every joint (ranges ignored, as the bound ignores
    /// them), elbows stretched and folded among them, moved by up to half the solver's
    /// tolerances. On the spherical-wrist arms it refuses some of the poses their nominal
    /// twins reach and of those poses pushed up to a tenth of the reach away from the base, and
    /// for every goal it refuses, the search without it (from the table's nearest and spread
    /// starts) finds no solution either.
    #[test]
    fn the_reach_bound_refuses_only_what_the_search_cannot_reach() {
        use rand::{RngExt, SeedableRng};
        for (name, nominal, calibrated) in reach_test_arms() {
            let bound =
                ReachBound::new(&calibrated, Target::EndEffector, 1e-6, 1e-6).expect("a 6R arm");
            let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(5);
            let chain = Chain::new(&calibrated);
            let mut turn = |robot: &Robot| -> Vec<f64> {
                robot
                    .joints
                    .iter()
                    .map(|j| g.random_range(-3.2..3.2) / j.slope.abs())
                    .collect()
            };
            for k in 0..20_000 {
                let mut f = chain.frame_at(&turn(&calibrated), Target::EndEffector);
                f.translation.x += 4e-7;
                f.translation.y -= 4e-7;
                assert!(!bound.out_of_reach(&f), "{name}: reached pose {k} refused");
            }
            // Nominal poses, some pushed away from the base (by 0, 2, ..., 10 % of the reach).
            let nominal_chain = Chain::new(&nominal);
            let l = &calibrated.links[0];
            let base = Vector3::new(l.x, l.y, l.z);
            let reach = calibrated.reach();
            let goals: Vec<Goal> = (0..300)
                .map(|k| {
                    let mut f = nominal_chain.frame_at(&turn(&nominal), Target::EndEffector);
                    let away = (f.translation - base).normalize();
                    f.translation += away * 0.02 * reach * (k % 6) as f64;
                    Goal::Pose(f)
                })
                .collect();
            let mut search = TargetSearch::new(&calibrated, &nominal, Options::default())
                .unwrap()
                .without_reach_bound();
            let mut out = vec![0.0; 6];
            let mut refused = 0;
            for (k, goal) in goals.iter().enumerate() {
                let Goal::Pose(f) = goal else { unreachable!() };
                if bound.out_of_reach(f) {
                    refused += 1;
                    let s = search.solve(goal, Target::EndEffector, None, &mut out);
                    assert!(s.flags.unreachable, "{name}: goal {k} refused, yet reached");
                }
            }
            if name != "random 6R" {
                assert!(refused >= 20, "{name}: {refused} of 300 goals refused");
            }
        }
    }

    /// A seeded pose goal the reach bound proves out of reach is tried from its seed alone
    /// (and that attempt polished), not from the table's starts: on the nominal poses the
    /// IRB 120's calibrated twin cannot reach, less than a third of the forward kinematics of
    /// the search without the bound, and the same flag `unreachable` on every row.
    #[test]
    fn a_goal_out_of_reach_is_tried_from_its_seed_alone() {
        let (_, nominal, calibrated) = reach_test_arms().remove(1);
        let bound = ReachBound::new(&calibrated, Target::EndEffector, 1e-6, 1e-6).unwrap();
        let (_, seeded) = seeded_targets(&nominal, 1000, 5);
        let refused: Goals = seeded
            .into_iter()
            .filter(|(g, _)| matches!(g, Goal::Pose(f) if bound.out_of_reach(f)))
            .collect();
        assert!(refused.len() >= 20, "{} refused", refused.len());
        let cost = |with_bound: bool| {
            let s = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
            let mut s = if with_bound {
                s
            } else {
                s.without_reach_bound()
            };
            let mut out = vec![0.0; 6];
            for (g, seed) in &refused {
                let r = s.solve(g, Target::EndEffector, seed.as_deref(), &mut out);
                assert!(r.flags.unreachable);
            }
            s.evaluations()
        };
        let (with, without) = (cost(true), cost(false));
        assert!(
            3 * with < without,
            "{with} against {without} forward kinematics over {} goals",
            refused.len()
        );
    }

    /// A seeded pose goal its seed does not reach is tried from the closed form's branches, and
    /// when none of them reaches it either, the table's starts are not tried: on the IRB 120 and
    /// a random spherical-wrist arm (400 poses of the nominal programs, seeded by their
    /// readings and moved 0, 1 or 2 mm away from the base, so that some lie just beyond the
    /// calibrated twin's reach, where the reach bound cannot prove it), no row is flagged worse
    /// than with the table's starts tried instead, and the whole costs fewer forward kinematics
    /// (measured: 0.86 and 0.85 of them, with 14 and 51 goals unreachable).
    #[test]
    fn a_seeded_goal_no_branch_reaches_skips_the_table() {
        for (name, nominal, calibrated) in reach_test_arms().into_iter().take(2) {
            let (_, seeded) = seeded_targets(&nominal, 400, 6);
            let base = calibrated.links[0].x * Vector3::x()
                + calibrated.links[0].y * Vector3::y()
                + calibrated.links[0].z * Vector3::z();
            let goals: Goals = seeded
                .into_iter()
                .enumerate()
                .map(|(k, (g, seed))| {
                    let Goal::Pose(mut f) = g else { unreachable!() };
                    let away = (f.translation - base).normalize();
                    f.translation += away * 1e-3 * (k % 3) as f64;
                    (Goal::Pose(f), seed)
                })
                .collect();
            let solve = |branches: bool| {
                let s = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
                let mut s = if branches {
                    s
                } else {
                    s.without_branches_when_seed_fails()
                };
                let mut out = vec![0.0; 6];
                let flags: Vec<Flags> = goals
                    .iter()
                    .map(|(g, seed)| {
                        s.solve(g, Target::EndEffector, seed.as_deref(), &mut out)
                            .flags
                    })
                    .collect();
                (flags, s.evaluations())
            };
            let ((new, cost_new), (old, cost_old)) = (solve(true), solve(false));
            for (k, (a, b)) in new.iter().zip(&old).enumerate() {
                assert!(
                    flag_rank(a) <= flag_rank(b),
                    "{name}: goal {k}: {a:?} against {b:?}"
                );
            }
            let unreachable = new.iter().filter(|f| f.unreachable).count();
            assert!(unreachable >= 10, "{name}: {unreachable} goals unreachable");
            assert!(
                cost_new < cost_old,
                "{name}: {cost_new} against {cost_old} forward kinematics"
            );
        }
    }

    /// An unseeded pose goal that the closed form's branches and the nearest starts find only at
    /// a singularity skips the spread starts, and no row is flagged otherwise for it: on the
    /// arms of the reach bound's tests (a spherical-wrist arm, the IRB 120, and a random 6R arm
    /// with the general form, whose complete branches, all the rigid arm's solutions, settle
    /// such a goal without any start of the table), over the poses
    /// and positions the calibrated twin reaches at 400 postures, every row has the same flags
    /// as with the spread starts tried, some goals at a singularity, and fewer forward
    /// kinematics.
    #[test]
    fn a_goal_singular_from_the_nearest_starts_skips_the_spread_ones() {
        for (name, nominal, calibrated) in reach_test_arms() {
            let postures: Vec<Vec<f64>> = sample_postures(&nominal, 400, 5)
                .into_iter()
                .map(|p| p.readings)
                .collect();
            let reached = poses(&calibrated, &postures);
            let goals: Vec<Goal> = reached
                .iter()
                .map(|f| Goal::Pose(*f))
                .chain(reached.iter().map(|f| Goal::Position(f.translation)))
                .collect();
            let solve = |skip: bool| {
                let s = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
                let mut s = if skip { s } else { s.with_table_if_singular() };
                let mut out = vec![0.0; 6];
                let rows: Vec<(Flags, Vec<f64>)> = goals
                    .iter()
                    .map(|g| {
                        let flags = s.solve(g, Target::EndEffector, None, &mut out).flags;
                        (flags, out.clone())
                    })
                    .collect();
                (rows, s.evaluations(), s.settled_at_singularity)
            };
            let ((skipping, cost_skipping, settled), (trying, cost_trying, _)) =
                (solve(true), solve(false));
            let singular = skipping.iter().filter(|(f, _)| f.singular).count();
            for (k, ((a, u), (b, v))) in skipping.iter().zip(&trying).enumerate() {
                assert_eq!(a, b, "{name}: goal {k}");
                // On the general form's arm, the same solution up to whole turns (placed near
                // the previous row's): its singular goals keep theirs, so the rows after them
                // keep their references. (Elsewhere the spread starts may find another
                // solution for a singular goal, and the next rows then another as good.)
                let moved = u.iter().zip(v).zip(&calibrated.joints).any(|((x, y), j)| {
                    super::super::configuration::wrap_pi((x - y) * j.slope).abs() > 1e-6
                });
                assert!(
                    !(moved && name == "random 6R"),
                    "{name}: goal {k}: {u:?} against {v:?}"
                );
            }
            assert!(singular > 0, "{name}: no goal at a singularity");
            // The general form settles singular goals by its branches alone (measured: 7 of
            // the random arm's 400 pose goals).
            if name == "random 6R" {
                assert!(
                    settled > 0,
                    "{name}: no goal settled at a singularity by the branches"
                );
            }
            assert!(
                cost_skipping < cost_trying,
                "{name}: {cost_skipping} against {cost_trying} forward kinematics"
            );
        }
    }

    /// A random arm of six joints, one of them prismatic, has no closed form: its targets go
    /// through the table of starts, as without the closed form (the same solutions), and are
    /// reached.
    #[test]
    fn an_arm_outside_the_families_falls_back_to_the_search() {
        use JointKind::{Prismatic, Revolute};
        let kinds = [Revolute, Revolute, Prismatic, Revolute, Revolute, Revolute];
        let (nominal, calibrated) = twin(crate::apps::simulate::random_robot(&kinds, 21), 22);
        let postures: Vec<Vec<f64>> = sample_postures(&nominal, 100, 4)
            .into_iter()
            .map(|p| p.readings)
            .collect();
        let goals: Vec<(Goal, Option<Vec<f64>>)> = poses(&calibrated, &postures)
            .into_iter()
            .map(|f| (Goal::Pose(f), None))
            .collect();
        let mut search = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
        assert!(!search.has_closed_form(Target::EndEffector));
        let mut out = vec![0.0; 6];
        let unreachable = goals
            .iter()
            .filter(|(g, _)| {
                search
                    .solve(g, Target::EndEffector, None, &mut out)
                    .flags
                    .unreachable
            })
            .count();
        assert_eq!(unreachable, 0);
        let (c, p, d, w) = both_ways(&nominal, &calibrated, &goals, None);
        assert_eq!((c, w), (p, 0));
        assert!(d < 1e-12, "{d}");
    }
}
