//! Whether recorded speeds and headings agree with how the recorded positions move. A speed
//! column in km/h or mph, headings in degrees, reversed or measured from another axis all look
//! like plausible numbers row by row; against the motion they are off by a factor or an angle.
//! Used by the loaders of vehicle recordings and of CommonRoad trajectories.

use std::f64::consts::PI;

/// Speed above which a displacement tells the direction and speed of travel (m/s): below it,
/// position noise dominates.
const MOVING: f64 = 2.0;
/// Recorded speed over the speed of the positions, median over moving steps: outside this,
/// the speed is in other units (km/h is 3.6x, mph 2.24x) or belongs to other rows.
const SPEED_RATIO: std::ops::RangeInclusive<f64> = 0.67..=1.5;
/// Largest median angle between the heading and the direction of travel (rad): slip angles
/// are a few hundredths; degrees, a reversed heading or another convention are far above.
const HEADING_MISMATCH: f64 = 0.5;
/// Floor of the positions' speed in a ratio (m/s), so a standing vehicle recorded as moving
/// gives a large ratio, not a division by zero.
const MIN_SPEED_OF_POSITIONS: f64 = 0.01;
/// Fewest moving steps that make a verdict: a vehicle standing or creeping is not judged.
const MIN_STEPS: usize = 3;

/// How a track's speeds or headings disagree with its positions.
#[derive(Debug, Clone, PartialEq)]
pub enum Mismatch {
    /// Recorded speed / speed of the positions (median) and the steps it is over.
    Speed { ratio: f64, steps: usize },
    /// Median angle (rad) between heading and direction of travel, and the steps.
    Heading { angle: f64, steps: usize },
}

impl Mismatch {
    /// The column (or field) at fault.
    pub fn column(&self) -> &'static str {
        match self {
            Mismatch::Speed { .. } => "speed",
            Mismatch::Heading { .. } => "heading",
        }
    }
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Mismatch::Speed { ratio, steps } => write!(
                f,
                "the recorded speed is {ratio:.2} times the speed of the positions (median over \
                 {steps} moving steps): km/h or mph, or a wrong time step? expected m/s, and \
                 positions that move as fast as the speed says"
            ),
            Mismatch::Heading { angle, steps } => write!(
                f,
                "the heading is {angle:.2} rad from the direction of travel (median over {steps} \
                 moving steps): degrees, reversed, or measured from another axis? expected \
                 radians, counter-clockwise from +x, along the motion"
            ),
        }
    }
}

/// Compares a track sampled every `period` seconds with its own motion, over displacements of
/// about a second (so position noise of a few decimetres does not pass for motion).
pub fn check(
    period: f64,
    x: &[f64],
    y: &[f64],
    heading: &[f64],
    speed: &[f64],
) -> Result<(), Mismatch> {
    let lag = ((1.0 / period).round() as usize).max(1);
    let mut ratios = Vec::new();
    let mut angles = Vec::new();
    for k in lag..x.len() {
        let j = k - lag;
        let (dx, dy) = (x[k] - x[j], y[k] - y[j]);
        let moved = dx.hypot(dy) / (lag as f64 * period);
        let recorded: f64 = speed[j..=k].iter().sum::<f64>() / (lag + 1) as f64;
        // Moving by either account: positions that barely move under recorded speeds say the
        // period (or the speed) is wrong, and must be judged.
        if moved < MOVING && recorded < MOVING {
            continue;
        }
        ratios.push(recorded / moved.max(MIN_SPEED_OF_POSITIONS));
        if moved >= MOVING {
            let diff = (heading[j + lag / 2] - dy.atan2(dx) + PI).rem_euclid(2.0 * PI) - PI;
            angles.push(diff.abs());
        }
    }
    if ratios.len() < MIN_STEPS {
        return Ok(());
    }
    let steps = ratios.len();
    let ratio = median(&mut ratios);
    if !SPEED_RATIO.contains(&ratio) {
        return Err(Mismatch::Speed { ratio, steps });
    }
    if angles.len() < MIN_STEPS {
        return Ok(());
    }
    let angle = median(&mut angles);
    if angle > HEADING_MISMATCH {
        return Err(Mismatch::Heading { angle, steps });
    }
    Ok(())
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vehicle at 15 m/s heading 0.3 rad, sampled at 10 Hz for 5 s.
    fn track() -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = 50;
        let (h, v) = (0.3f64, 15.0);
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.1).collect();
        (
            t.iter().map(|t| v * t * h.cos()).collect(),
            t.iter().map(|t| v * t * h.sin()).collect(),
            vec![h; n],
            vec![v; n],
        )
    }

    #[test]
    fn consistent_motion_passes_and_unit_mistakes_are_named() {
        let (x, y, heading, speed) = track();
        assert_eq!(check(0.1, &x, &y, &heading, &speed), Ok(()));
        let kmh: Vec<f64> = speed.iter().map(|v| v * 3.6).collect();
        assert!(matches!(
            check(0.1, &x, &y, &heading, &kmh),
            Err(Mismatch::Speed { ratio, .. }) if (ratio - 3.6).abs() < 1e-9
        ));
        let degrees: Vec<f64> = heading.iter().map(|h| h.to_degrees()).collect();
        assert!(matches!(
            check(0.1, &x, &y, &degrees, &speed),
            Err(Mismatch::Heading { .. })
        ));
        let reversed: Vec<f64> = heading.iter().map(|h| h + PI).collect();
        assert!(matches!(
            check(0.1, &x, &y, &reversed, &speed),
            Err(Mismatch::Heading { angle, .. }) if (angle - PI).abs() < 1e-9
        ));
    }

    #[test]
    fn a_wrong_period_is_named_whether_the_positions_seem_to_move_or_not() {
        let (x, y, heading, speed) = track();
        // Read every 0.9 s or 5 s, the positions move 9 or 50 times slower than recorded.
        for period in [0.9, 5.0] {
            assert!(
                matches!(
                    check(period, &x, &y, &heading, &speed),
                    Err(Mismatch::Speed { ratio, .. }) if ratio > 5.0
                ),
                "{period}"
            );
        }
    }

    #[test]
    fn a_standing_vehicle_is_not_judged() {
        let n = 30;
        let still = vec![0.0; n];
        assert_eq!(
            check(0.1, &still, &still, &vec![2.0; n], &vec![0.0; n]),
            Ok(())
        );
    }
}
