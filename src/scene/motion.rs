//! Rigid motion over the frame: keyframed translation, axis-angle rotation and uniform scale.
//!
//! Between keyframes translation and scale interpolate linearly and rotation by slerp, so a point's
//! path is an arc (Guan & Mueller §3.3: "rotations … computing each point's trajectory as the
//! local path in the global rotation"). Slerp takes the short way round, so consecutive keyframes
//! must turn less than 180°; [`Motion::new`] rejects larger steps.

use glam::{DAffine3, DMat3, DQuat, DVec3};

use super::{finite, finite3, positive};
use crate::error::{Error, Result};

/// An object's pose at one instant: world = translation + rotation · (scale · object).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// World position of the object's origin.
    pub translation: DVec3,
    /// Orientation.
    pub rotation: DQuat,
    /// Uniform scale.
    pub scale: f64,
}

impl Pose {
    /// The identity pose.
    pub const IDENTITY: Pose = Pose {
        translation: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
        scale: 1.0,
    };

    /// The pose as an affine transform.
    #[must_use]
    pub fn to_affine(&self) -> DAffine3 {
        DAffine3::from_scale_rotation_translation(
            DVec3::splat(self.scale),
            self.rotation,
            self.translation,
        )
    }

    /// The rotation part as a matrix (normals and tangent directions transform by it).
    #[must_use]
    pub fn rotation_matrix(&self) -> DMat3 {
        DMat3::from_quat(self.rotation)
    }
}

/// Smallest change of orientation, radians, that [`Motion::turns_within`] counts: a slerp
/// between equal keyframe rotations may drift by rounding, whose angle `acos` magnifies to about
/// 10⁻⁸.
pub const TURN_EPSILON: f64 = 1e-6;

/// Most keyframes one object may have. The plan measures the motion over every interval between
/// keyframes, and each interval may be cut into sub-segments and drawn: a 25-surfel square
/// through 10,000 keyframes (`tests/data/worst-cases/zigzag-10000-keyframes.toml.gz`, 64 × 48)
/// takes 0.06 s with `static`, 0.5 s with `blur` and 16 s with a hint whose ring-shaped trail
/// is drawn as motion ellipses, the square's share of the 2²⁴ of them.
pub const MAX_KEYFRAMES: usize = 10_000;

/// A pose at a normalized frame time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    /// Normalized frame time.
    pub t: f64,
    /// The pose at `t`.
    pub pose: Pose,
}

/// Keyframes sorted by time; before the first and after the last the pose holds still.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    keyframes: Vec<Keyframe>,
}

impl Motion {
    /// A motion through `keyframes` (none: still at the identity pose). Each keyframe's time must
    /// lie in [0, 1] and increase, its translation be finite, its rotation finite (it is
    /// normalized) and less than 180° from the previous one, and its scale finite and positive;
    /// there may be at most [`MAX_KEYFRAMES`]. Errors name the keyframe and field, e.g.
    /// `keyframe[2].t`.
    pub fn new(keyframes: Vec<Keyframe>) -> Result<Self> {
        if keyframes.len() > MAX_KEYFRAMES {
            return Err(Error::invalid(
                "keyframe",
                format!(
                    "{} keyframes; an object may have at most {MAX_KEYFRAMES} in its frame (the \
                     plan measures every interval between them, and each may be cut further)",
                    keyframes.len()
                ),
            ));
        }
        let mut checked: Vec<Keyframe> = Vec::with_capacity(keyframes.len());
        for (k, key) in keyframes.into_iter().enumerate() {
            let field = |name: &str| format!("keyframe[{k}].{name}");
            let t = finite(&field("t"), key.t)?;
            if !(0.0..=1.0).contains(&t) {
                return Err(Error::invalid(
                    field("t"),
                    format!("{t} is outside the frame: keyframe times are in [0, 1]"),
                ));
            }
            let rotation = key.pose.rotation;
            let length = rotation.length();
            if !(length.is_finite() && length > 0.0) {
                return Err(Error::invalid(
                    field("rotate"),
                    "must be a finite, non-zero quaternion",
                ));
            }
            // A rotation given as a unit quaternion is kept bit for bit.
            let rotation = if (length - 1.0).abs() <= 1e-12 {
                rotation
            } else {
                rotation / length
            };
            if let Some(previous) = checked.last() {
                if !(t > previous.t) {
                    return Err(Error::invalid(
                        field("t"),
                        format!(
                            "keyframe times must increase: {t} comes after {}",
                            previous.t
                        ),
                    ));
                }
                // A negative dot product of the quaternions means the long way round, which
                // slerp cannot take; within 10⁻⁹ of zero (a step within 1.15·10⁻⁷° of a half
                // turn) the rounding of the quaternions may take either way.
                if previous.pose.rotation.dot(rotation) <= 1e-9 {
                    return Err(Error::invalid(
                        field("rotate"),
                        "turns 180° or more from the previous keyframe, or so near it (within 1.15e-7°) that rounding \
                         may take the long way; rotation is interpolated by slerp, which takes the shorter way, so \
                         keyframes must be less than 180° apart: add keyframes in between",
                    ));
                }
            }
            checked.push(Keyframe {
                t,
                pose: Pose {
                    translation: finite3(&field("translate"), key.pose.translation)?,
                    rotation,
                    scale: positive(&field("scale"), key.pose.scale)?,
                },
            });
        }
        if checked.is_empty() {
            return Ok(Motion::still(Pose::IDENTITY));
        }
        Ok(Motion { keyframes: checked })
    }

    /// An object that does not move.
    #[must_use]
    pub fn still(pose: Pose) -> Self {
        Motion {
            keyframes: vec![Keyframe { t: 0.0, pose }],
        }
    }

    /// The pose at time `t`.
    #[must_use]
    pub fn pose_at(&self, t: f64) -> Pose {
        let keys = &self.keyframes;
        // The first keyframe at or after t (binary search: scenes may have many keyframes).
        let next = keys.partition_point(|k| k.t < t);
        if next == 0 {
            return keys[0].pose;
        }
        if next == keys.len() {
            return keys[next - 1].pose;
        }
        if keys[next].t == t {
            return keys[next].pose;
        }
        let (a, b) = (keys[next - 1], keys[next]);
        let s = (t - a.t) / (b.t - a.t);
        Pose {
            translation: a.pose.translation.lerp(b.pose.translation, s),
            rotation: a.pose.rotation.slerp(b.pose.rotation, s).normalize(),
            scale: a.pose.scale + (b.pose.scale - a.pose.scale) * s,
        }
    }

    /// Whether the pose changes anywhere inside [t0, t1].
    #[must_use]
    pub fn moves_within(&self, t0: f64, t1: f64) -> bool {
        let reference = self.pose_at(t0);
        self.any_pose_within(t0, t1, |pose| pose != reference)
    }

    /// Whether the orientation changes anywhere inside [t0, t1] by more than [`TURN_EPSILON`].
    #[must_use]
    pub fn turns_within(&self, t0: f64, t1: f64) -> bool {
        let reference = self.pose_at(t0).rotation;
        self.any_pose_within(t0, t1, |pose| {
            pose.rotation.angle_between(reference) > TURN_EPSILON
        })
    }

    /// Whether `differs` holds at a keyframe inside (t0, t1] or at t1. Poses between keyframes
    /// interpolate those at their ends, so a change anywhere in [t0, t1] shows at one of these.
    fn any_pose_within(&self, t0: f64, t1: f64, differs: impl Fn(Pose) -> bool) -> bool {
        self.keyframes_from(t0, |t| t <= t1)
            .iter()
            .map(|k| k.t)
            .chain(std::iter::once(t1))
            .any(|t| differs(self.pose_at(t)))
    }

    /// t0, the keyframe times strictly inside (t0, t1), and t1: the ends of the pieces between
    /// which the pose changes smoothly.
    #[must_use]
    pub fn keyframe_ends(&self, t0: f64, t1: f64) -> Vec<f64> {
        let mut ends = vec![t0];
        ends.extend(self.breaks_within(t0, t1));
        ends.push(t1);
        ends
    }

    /// Keyframe times strictly inside (t0, t1): the points where a path may bend sharply.
    pub fn breaks_within(&self, t0: f64, t1: f64) -> impl Iterator<Item = f64> + '_ {
        self.keyframes_from(t0, |t| t < t1).iter().map(|k| k.t)
    }

    /// The keyframes after `t0` for which `before_end` holds of their time (true up to some time,
    /// false from there on), found by binary search: the plan asks this of every interval
    /// between keyframes, and a scan of them all made it quadratic in their count (100,000
    /// keyframes took 19 s).
    fn keyframes_from(&self, t0: f64, before_end: impl Fn(f64) -> bool) -> &[Keyframe] {
        let keys = &self.keyframes;
        let start = keys.partition_point(|k| k.t <= t0);
        let end = start + keys[start..].partition_point(|k| before_end(k.t));
        &keys[start..end]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spin(degrees: f64) -> Motion {
        Motion::new(vec![
            Keyframe {
                t: 0.0,
                pose: Pose::IDENTITY,
            },
            Keyframe {
                t: 1.0,
                pose: Pose {
                    translation: DVec3::new(2.0, 0.0, 0.0),
                    rotation: DQuat::from_axis_angle(DVec3::Z, degrees.to_radians()),
                    scale: 2.0,
                },
            },
        ])
        .unwrap()
    }

    #[test]
    fn rotation_paths_are_arcs_at_constant_angular_speed() {
        let motion = spin(90.0);
        for i in 0..=10 {
            let t = i as f64 / 10.0;
            let p = motion.pose_at(t).rotation * DVec3::X;
            let angle = p.y.atan2(p.x).to_degrees();
            assert!((angle - 90.0 * t).abs() < 1e-9, "t={t}: {angle}");
            assert!((p.length() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn a_motion_turns_only_where_its_keyframes_differ_in_rotation() {
        let held = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        let key = |t: f64, x: f64, rotation: DQuat| Keyframe {
            t,
            pose: Pose {
                translation: DVec3::new(x, 0.0, 0.0),
                rotation,
                scale: 1.0,
            },
        };
        let sliding = Motion::new(vec![key(0.0, 0.0, held), key(1.0, 3.0, held)]).unwrap();
        // Between equal rotations the slerp only rounds: no turn, however the window falls.
        assert!(sliding.moves_within(0.3, 0.7) && !sliding.turns_within(0.3, 0.7));
        // Turning away and back: the keyframe between shows the turn.
        let back = Motion::new(vec![
            key(0.0, 0.0, held),
            key(0.5, 1.0, DQuat::IDENTITY),
            key(1.0, 2.0, held),
        ])
        .unwrap();
        assert!(back.turns_within(0.0, 1.0) && !back.turns_within(0.0, 0.0));
        assert!(spin(0.001).turns_within(0.2, 0.4));
    }

    #[test]
    fn translation_and_scale_interpolate_linearly_and_hold_outside() {
        let motion = spin(10.0);
        let mid = motion.pose_at(0.25);
        assert!((mid.translation - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-12);
        assert!((mid.scale - 1.25).abs() < 1e-12);
        assert_eq!(motion.pose_at(-1.0), Pose::IDENTITY);
        assert_eq!(motion.pose_at(2.0), motion.pose_at(1.0));
    }

    #[test]
    fn no_keyframes_hold_still_and_bad_ones_are_named() {
        assert_eq!(
            Motion::new(Vec::new()).unwrap(),
            Motion::still(Pose::IDENTITY)
        );
        let key = |t, degrees: f64, scale| Keyframe {
            t,
            pose: Pose {
                rotation: DQuat::from_rotation_y(degrees.to_radians()),
                scale,
                ..Pose::IDENTITY
            },
        };
        let error = |keys: Vec<Keyframe>| Motion::new(keys).unwrap_err().to_string();
        assert!(error(vec![key(0.5, 0.0, 1.0), key(0.2, 0.0, 1.0)])
            .starts_with("keyframe[1].t: keyframe times must increase"));
        assert!(error(vec![key(1.5, 0.0, 1.0)]).starts_with("keyframe[0].t: 1.5 is outside"));
        assert!(error(vec![key(0.0, 0.0, 1.0), key(1.0, 200.0, 1.0)])
            .starts_with("keyframe[1].rotate: turns 180° or more"));
        assert!(error(vec![key(0.0, 0.0, -1.0)]).starts_with("keyframe[0].scale: "));
        let mut nan = key(0.0, 0.0, 1.0);
        nan.pose.translation.y = f64::NAN;
        assert!(error(vec![nan]).starts_with("keyframe[0].translate[1]: "));
        // A quaternion that is not unit length is normalized.
        let mut long = key(0.0, 90.0, 1.0);
        long.pose.rotation *= 2.0;
        let motion = Motion::new(vec![long]).unwrap();
        assert!((motion.pose_at(0.0).rotation.length() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_still_object_does_not_move() {
        let still = Motion::still(Pose::IDENTITY);
        assert!(!still.moves_within(0.0, 1.0));
        assert!(spin(5.0).moves_within(0.0, 1.0));
        assert!(!spin(5.0).moves_within(1.0, 1.5));
    }
}
