//! Rigid motion over the frame: keyframed translation, axis-angle rotation and uniform scale.
//!
//! Between keyframes translation and scale interpolate linearly and rotation by slerp, so a point's
//! path is an arc (Guan & Mueller §3.3: "rotations … computing each point's trajectory as the
//! local path in the global rotation"). Slerp takes the short way round, so keyframes may be at
//! most 180° apart; the scene loader rejects larger steps.

use glam::{DAffine3, DMat3, DQuat, DVec3};

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
    /// A motion through `keyframes`, or `None` unless they are non-empty and sorted by time (the
    /// scene loader checks both first and names the field).
    #[must_use]
    pub fn new(keyframes: Vec<Keyframe>) -> Option<Self> {
        let sorted = keyframes.windows(2).all(|w| w[0].t <= w[1].t);
        (!keyframes.is_empty() && sorted).then_some(Motion { keyframes })
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
        self.keyframes
            .iter()
            .map(|k| k.t)
            .filter(|&t| t > t0 && t <= t1)
            .chain(std::iter::once(t1))
            .any(|t| self.pose_at(t) != reference)
    }

    /// Keyframe times strictly inside (t0, t1): the points where a path may bend sharply.
    pub fn breaks_within(&self, t0: f64, t1: f64) -> impl Iterator<Item = f64> + '_ {
        self.keyframes
            .iter()
            .map(|k| k.t)
            .filter(move |&t| t > t0 && t < t1)
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
    fn translation_and_scale_interpolate_linearly_and_hold_outside() {
        let motion = spin(10.0);
        let mid = motion.pose_at(0.25);
        assert!((mid.translation - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-12);
        assert!((mid.scale - 1.25).abs() < 1e-12);
        assert_eq!(motion.pose_at(-1.0), Pose::IDENTITY);
        assert_eq!(motion.pose_at(2.0), motion.pose_at(1.0));
    }

    #[test]
    fn empty_or_unsorted_keyframes_make_no_motion() {
        assert!(Motion::new(Vec::new()).is_none());
        let key = |t| Keyframe {
            t,
            pose: Pose::IDENTITY,
        };
        assert!(Motion::new(vec![key(0.5), key(0.2)]).is_none());
    }

    #[test]
    fn a_still_object_does_not_move() {
        let still = Motion::still(Pose::IDENTITY);
        assert!(!still.moves_within(0.0, 1.0));
        assert!(spin(5.0).moves_within(0.0, 1.0));
        assert!(!spin(5.0).moves_within(1.0, 1.5));
    }
}
