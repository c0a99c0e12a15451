//! The sines and cosines of a dataset's joint readings, kept with the dataset: every pass of
//! forward kinematics over the same postures (the data check, the solver's start, the report's
//! errors before and after) shares one table instead of a sine and a cosine per joint per
//! posture per pass ([`ReadingTrig`]).

use std::sync::{Arc, Mutex};

use super::Posture;
use crate::model::kinematics::ReadingTrig;
use crate::model::robot::Robot;

/// Tables kept: a calibration that estimates slopes alternates two sets of them (before and
/// after), so two tables serve it without rebuilding.
const KEPT: usize = 2;

/// The tables made for a dataset's postures, most recent first. A table is handed out only when
/// it fits the robot's slopes and couplings ([`ReadingTrig::fits`]) and was made from exactly
/// the readings the dataset holds now (compared value by value: the postures are public and may
/// change after a table was made).
#[derive(Default)]
pub(crate) struct TrigCache {
    tables: Mutex<Vec<Made>>,
}

/// A table and the readings it was made from, posture after posture.
struct Made {
    table: Arc<ReadingTrig>,
    readings: Vec<f64>,
}

impl TrigCache {
    /// The table of `postures`' readings for `robot`'s slopes and couplings, made now if no
    /// kept one fits.
    pub(crate) fn get(&self, robot: &Robot, postures: &[Posture]) -> Arc<ReadingTrig> {
        let mut tables = self.tables.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = tables
            .iter()
            .position(|m| m.table.fits(robot) && same_readings(&m.readings, postures))
        {
            let made = tables.remove(i);
            let table = made.table.clone();
            tables.insert(0, made);
            return table;
        }
        let table = Arc::new(ReadingTrig::new(
            robot,
            postures.iter().map(|p| p.readings.as_slice()),
        ));
        // Made at its size: collected from a flattening iterator it would grow by doubling.
        let mut readings = Vec::with_capacity(postures.iter().map(|p| p.readings.len()).sum());
        for p in postures {
            readings.extend_from_slice(&p.readings);
        }
        tables.insert(
            0,
            Made {
                table: table.clone(),
                readings,
            },
        );
        tables.truncate(KEPT);
        table
    }
}

/// Whether `flat` holds exactly `postures`' readings, in order (bit for bit, so that a NaN
/// reading matches itself and -0 does not match 0).
fn same_readings(flat: &[f64], postures: &[Posture]) -> bool {
    let mut at = 0;
    for p in postures {
        let Some(kept) = flat.get(at..at + p.readings.len()) else {
            return false;
        };
        if !kept
            .iter()
            .zip(&p.readings)
            .all(|(a, b)| a.to_bits() == b.to_bits())
        {
            return false;
        }
        at += p.readings.len();
    }
    at == flat.len()
}

impl Clone for TrigCache {
    fn clone(&self) -> Self {
        let tables = self.tables.lock().unwrap_or_else(|e| e.into_inner());
        TrigCache {
            tables: Mutex::new(
                tables
                    .iter()
                    .map(|m| Made {
                        table: m.table.clone(),
                        readings: m.readings.clone(),
                    })
                    .collect(),
            ),
        }
    }
}

impl std::fmt::Debug for TrigCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.tables.lock().map_or(0, |t| t.len());
        write!(f, "TrigCache({n} tables)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    fn postures(values: &[[f64; 4]]) -> Vec<Posture> {
        values
            .iter()
            .enumerate()
            .map(|(i, r)| Posture {
                label: i.to_string(),
                readings: r.to_vec(),
                session: None,
                payload: None,
            })
            .collect()
    }

    #[test]
    fn a_table_is_reused_only_for_the_same_readings_and_slopes() {
        // The GE A4 is RRPR: joints 0 and 1 are revolute.
        let robot = crate::model::examples::ge_a4();
        let cache = TrigCache::default();
        let mut ps = postures(&[[0.1, 0.2, 1.0, 0.0], [0.3, -0.4, 2.0, 0.5]]);
        let a = cache.get(&robot, &ps);
        assert!(Arc::ptr_eq(&a, &cache.get(&robot, &ps)));
        assert_eq!(a.posture(1)[1], (robot.joints[1].slope * -0.4).sin_cos());
        // A reading changed after the table was made: a new table, with the new value.
        ps[1].readings[1] = 0.5;
        let b = cache.get(&robot, &ps);
        assert!(!Arc::ptr_eq(&a, &b));
        assert_eq!(b.posture(1)[1], (robot.joints[1].slope * 0.5).sin_cos());
        // Other slopes: another table; both are kept.
        let mut sloped = robot.clone();
        sloped.joints[0].slope = 2.0;
        let c = cache.get(&sloped, &ps);
        assert_eq!(c.posture(1)[0], (2.0 * 0.3f64).sin_cos());
        // A prismatic joint's entry is (0, 1).
        assert_eq!(c.posture(0)[2], (0.0, 1.0));
        assert!(Arc::ptr_eq(&b, &cache.get(&robot, &ps)));
        assert!(Arc::ptr_eq(&c, &cache.get(&sloped, &ps)));
        // A posture dropped: not the same readings.
        ps.pop();
        assert!(!Arc::ptr_eq(&b, &cache.get(&robot, &ps)));
    }
}
