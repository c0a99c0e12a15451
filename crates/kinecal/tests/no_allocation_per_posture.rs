//! The hot path allocates nothing per posture: forward kinematics and the Jacobian columns of a
//! serial, a tree and an elastic robot allocate nothing once their workspace has seen a posture
//! (an elastic robot's sizes its response then), and
//! a pass of the problem with its full Jacobian allocates as often for 2,000 postures as for 200
//! (its buffers are made per pass, not per posture). Counted by a global allocator that tallies
//! each thread's allocations apart (the library's hot path runs on the calling thread), so the
//! test harness's own threads and the other tests cannot add to a count.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Mutex;

use kinecal::apps::simulate;
use kinecal::linalg::Matrix;
use kinecal::model::kinematics::ColumnPlan;
use kinecal::solve::problem::Problem;
use kinecal::{Chain, JointKind, ParamId, Robot, Target, Workspace};

struct Counting;

thread_local! {
    /// This thread's allocations (a const-initialised cell: counting allocates nothing).
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Counts one allocation of the calling thread (none while the thread is being torn down).
fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The allocations `f` makes on this thread.
fn allocations(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(Cell::get);
    f();
    ALLOCATIONS.with(Cell::get) - before
}

fn elastic(mut robot: Robot) -> Robot {
    let bodies = (1..=robot.dof())
        .map(|joint| kinecal::model::robot::Body {
            joint,
            mass: 2.0,
            com: nalgebra::Vector3::new(0.1, 0.0, 0.05),
        })
        .collect();
    let mut model = kinecal::model::robot::Elastic::new(&robot, bodies);
    for j in &mut model.joints {
        j.compliance = 2e-4;
        j.lateral = 1e-4;
    }
    robot.elastic = Some(model);
    robot
}

/// The allocations of forward kinematics and the Jacobian of the end effector at `count`
/// postures of `robot`, after one posture has sized the workspace.
fn hot_path_allocations(robot: &Robot, count: usize) -> usize {
    let postures = simulate::sample_postures(robot, count, 1);
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let plan = ColumnPlan::all(robot, Target::EndEffector);
    let mut block = vec![0.0; 6 * plan.width()];
    chain.forward(&postures[0].readings, &mut ws);
    chain.jacobian_columns(&ws, &plan, &mut block);
    let n = allocations(|| {
        for p in &postures {
            chain.forward(&p.readings, &mut ws);
            chain.jacobian_columns(&ws, &plan, &mut block);
        }
    });
    assert!(block.iter().all(|v| v.is_finite()));
    n
}

#[test]
fn forward_kinematics_and_jacobian_columns_allocate_nothing_per_posture() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // The counter sees an allocation where there is one.
    assert_eq!(allocations(|| drop(std::hint::black_box(vec![1u8; 10]))), 1);
    let serial = simulate::random_robot(&[JointKind::Revolute; 6], 42);
    let tree = simulate::random_tree(2, &[6, 6], 42);
    for (what, robot) in [("serial", &serial), ("tree", &tree)] {
        let n = hot_path_allocations(robot, 200);
        assert_eq!(n, 0, "{what}: {n} allocations over 200 postures");
    }
    // An elastic robot: none that grows with the postures.
    let robot = elastic(serial);
    let (few, many) = (
        hot_path_allocations(&robot, 200),
        hot_path_allocations(&robot, 2000),
    );
    assert!(
        many <= few,
        "elastic: {few} allocations for 200 postures, {many} for 2,000"
    );
}

#[test]
fn a_pass_of_the_problem_allocates_the_same_for_ten_times_the_postures() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let robot = simulate::random_robot(&[JointKind::Revolute; 6], 7);
    let ids: Vec<ParamId> = robot.param_ids().take(30).collect();
    let per_pass = |count: usize| {
        let data = simulate::measure(&robot, &simulate::sample_postures(&robot, count, 2), false);
        let opts = kinecal::identifiability::AnalysisOptions::default();
        let p = Problem::new(&robot, &data, &ids, opts.weights, opts.orientation);
        let mut r = vec![0.0; p.rows()];
        let mut jac = Matrix::zeros(p.rows(), p.cols());
        p.evaluate(&robot, &mut r, Some(&mut jac));
        allocations(|| {
            p.evaluate(&robot, &mut r, Some(&mut jac));
        })
    };
    let (few, many) = (per_pass(200), per_pass(2000));
    assert_eq!(
        few, many,
        "a pass allocates {few} times for 200 postures, {many} for 2,000"
    );
    assert!(few < 50, "{few} allocations per pass");
}
