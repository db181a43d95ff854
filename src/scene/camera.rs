//! Pinhole camera: world → camera space → pixels, and the Jacobian of that projection.
//!
//! Conventions: right-handed world, the camera looks down its −Z, pixel (0,0) is the top-left pixel
//! and pixel centres sit at half-integers, so the image centre is (width/2, height/2).

use glam::{DAffine3, DMat3, DVec2, DVec3};

use super::{finite3, positive};
use crate::error::{shown, Error, Result};

/// Largest image side accepted, px.
pub const MAX_IMAGE_SIDE: u32 = 8192;

/// Spatial samples per pixel where triangles are drawn, unless the scene says otherwise.
pub const DEFAULT_SPATIAL_SAMPLES: u32 = 4;

/// Most spatial samples per pixel (an 8 × 8 grid).
pub const MAX_SPATIAL_SAMPLES: u32 = 64;

/// Narrowest vertical field of view, degrees (3.6 arc seconds: a focal length of 6·10⁷ px for
/// a 1024 px image). Narrower, screen positions outgrow what the plan's paths and the
/// rasterizer's single-precision footprints hold: at 10⁻²⁰° a floor and a cube took `analytic`
/// 13.6 s at 64 × 48 with screen paths of infinite length.
pub const MIN_FOV_Y_DEGREES: f64 = 1e-3;

/// A pinhole camera with its image size.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// World → camera (view) transform.
    pub view: DAffine3,
    /// Camera position in world space.
    pub eye: DVec3,
    /// Focal length in pixels: `(height / 2) / tan(fov_y / 2)`.
    pub focal_px: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Points closer than this (camera-space depth) are not projected.
    pub near: f64,
    /// Spatial samples per pixel where triangles are drawn: a square number, the centres of an
    /// n × n grid of equal cells (docs/conventions.md, "Spatial samples").
    pub spatial_samples: u32,
}

/// The 2×3 Jacobian of the projection at a camera-space point: rows are ∂x_px/∂p and ∂y_px/∂p.
#[derive(Clone, Copy, Debug)]
pub struct ProjectionJacobian {
    /// ∂x_px/∂p.
    pub row_x: DVec3,
    /// ∂y_px/∂p.
    pub row_y: DVec3,
}

impl ProjectionJacobian {
    /// The screen-space image of a camera-space vector (to first order).
    #[must_use]
    pub fn apply(&self, v: DVec3) -> DVec2 {
        DVec2::new(self.row_x.dot(v), self.row_y.dot(v))
    }
}

impl Camera {
    /// A camera at `eye` looking at `target` with `up` as the image's up direction,
    /// `fov_y_degrees` of vertical field of view and an image of `width` × `height` pixels; its
    /// near plane lies at a thousandth of the distance to the target ([`Camera::with_near`] sets
    /// it). Errors name the field: `eye`, `target`, `up` (not finite; target at the eye; up zero
    /// or along the view), `fov_y` (outside (0°, 180°)) or `width/height` (outside 1 to
    /// [`MAX_IMAGE_SIDE`]).
    pub fn new(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        fov_y_degrees: f64,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        let eye = finite3("eye", eye)?;
        let target = finite3("target", target)?;
        let up = finite3("up", up)?;
        let forward = target - eye;
        if !(forward.length() > 0.0) {
            return Err(Error::invalid("target", "must differ from camera.eye"));
        }
        // Finite points can lie further apart than a double holds (eye at 10³⁰⁰): the viewing
        // direction would be zero, and `up` blamed for it.
        if !forward.length().is_finite() {
            return Err(Error::invalid(
                "target",
                "lies too far from camera.eye: their distance is beyond a double's range",
            ));
        }
        if !(forward.normalize().cross(up).length() > 1e-9) {
            return Err(Error::invalid(
                "up",
                "must not be zero or parallel to the viewing direction",
            ));
        }
        let fov = super::finite("fov_y", fov_y_degrees)?;
        if !(MIN_FOV_Y_DEGREES..180.0).contains(&fov) {
            return Err(Error::invalid(
                "fov_y",
                format!(
                    "{}: the vertical field of view is in degrees, at least {MIN_FOV_Y_DEGREES} and below 180",
                    shown(fov)
                ),
            ));
        }
        check_image_size(width, height)?;
        let view = view_transform(eye, target, up);
        let focal_px = 0.5 * f64::from(height) / (0.5 * fov.to_radians()).tan();
        Ok(Camera {
            view,
            eye,
            focal_px,
            width,
            height,
            near: 1e-3 * forward.length(),
            spatial_samples: DEFAULT_SPATIAL_SAMPLES,
        })
    }

    /// The same camera drawing triangles with `samples` spatial samples per pixel: a square
    /// number from 1 to [`MAX_SPATIAL_SAMPLES`]; an error names `spatial_samples`.
    pub fn with_spatial_samples(mut self, samples: u32) -> Result<Camera> {
        Camera::check_spatial_samples(samples)?;
        self.spatial_samples = samples;
        Ok(self)
    }

    /// Whether `samples` spatial samples per pixel can be drawn (see
    /// [`Camera::with_spatial_samples`]); an error names `spatial_samples`.
    pub fn check_spatial_samples(samples: u32) -> Result<()> {
        let side = f64::from(samples).sqrt().round() as u32;
        if !(1..=MAX_SPATIAL_SAMPLES).contains(&samples) || side * side != samples {
            return Err(Error::invalid(
                "spatial_samples",
                format!(
                    "{samples}: samples per pixel form an n × n grid: 1, 4, 9, 16, 25, 36, 49 or {MAX_SPATIAL_SAMPLES}"
                ),
            ));
        }
        Ok(())
    }

    /// The spatial samples of pixel (0, 0) as offsets from its corner, in px: the centres of an
    /// n × n grid of equal cells, row by row.
    #[must_use]
    pub fn sample_offsets(&self) -> Vec<[f64; 2]> {
        let side = f64::from(self.spatial_samples).sqrt().round() as u32;
        let step = 1.0 / f64::from(side);
        (0..side)
            .flat_map(|j| {
                (0..side).map(move |i| [(f64::from(i) + 0.5) * step, (f64::from(j) + 0.5) * step])
            })
            .collect()
    }

    /// The camera-space direction of the ray through image point (x, y) px, scaled so that its
    /// depth (−z) is 1.
    #[must_use]
    pub fn ray(&self, x: f64, y: f64) -> DVec3 {
        DVec3::new(
            (x - 0.5 * f64::from(self.width)) / self.focal_px,
            (0.5 * f64::from(self.height) - y) / self.focal_px,
            -1.0,
        )
    }

    /// The same camera with its near plane at camera-space depth `near` (finite, positive).
    pub fn with_near(mut self, near: f64) -> Result<Camera> {
        self.near = positive("near", near)?;
        Ok(self)
    }

    /// The same camera with the image size and spatial samples per pixel a command line asks for
    /// in place of the scene's, where it asks ([`Camera::resized`],
    /// [`Camera::with_spatial_samples`]).
    pub fn overridden(
        &self,
        size: Option<(u32, u32)>,
        spatial_samples: Option<u32>,
    ) -> Result<Camera> {
        let mut camera = match size {
            Some((width, height)) => self.resized(width, height)?,
            None => self.clone(),
        };
        if let Some(samples) = spatial_samples {
            camera = camera.with_spatial_samples(samples)?;
        }
        Ok(camera)
    }

    /// The same camera with another image size (each side 1 to [`MAX_IMAGE_SIDE`]); the vertical
    /// field of view is kept.
    pub fn resized(&self, width: u32, height: u32) -> Result<Camera> {
        check_image_size(width, height)?;
        let mut camera = self.clone();
        camera.focal_px *= f64::from(height) / f64::from(self.height);
        camera.width = width;
        camera.height = height;
        Ok(camera)
    }

    /// Camera-space point → pixel position and depth (distance along −Z), or `None` when the
    /// point is not in front of the near plane.
    #[must_use]
    pub fn project(&self, p_view: DVec3) -> Option<(DVec2, f64)> {
        let depth = -p_view.z;
        if !(depth >= self.near) {
            return None;
        }
        let inv = self.focal_px / depth;
        Some((
            DVec2::new(
                0.5 * f64::from(self.width) + p_view.x * inv,
                0.5 * f64::from(self.height) - p_view.y * inv,
            ),
            depth,
        ))
    }

    /// Jacobian of [`Camera::project`] at a camera-space point in front of the camera.
    #[must_use]
    pub fn jacobian(&self, p_view: DVec3) -> ProjectionJacobian {
        let depth = -p_view.z;
        let inv = self.focal_px / depth;
        // x_px = cx + f x / d, y_px = cy - f y / d with d = -z, so ∂d/∂z = -1.
        ProjectionJacobian {
            row_x: DVec3::new(inv, 0.0, inv * p_view.x / depth),
            row_y: DVec3::new(0.0, -inv, -inv * p_view.y / depth),
        }
    }
}

/// Each side from 1 to [`MAX_IMAGE_SIDE`], or an error naming `width/height`.
pub fn check_image_size(width: u32, height: u32) -> Result<()> {
    if (1..=MAX_IMAGE_SIDE).contains(&width) && (1..=MAX_IMAGE_SIDE).contains(&height) {
        Ok(())
    } else {
        Err(Error::invalid(
            "width/height",
            format!("{width}×{height}: each side must be between 1 and {MAX_IMAGE_SIDE} pixels"),
        ))
    }
}

/// The right-handed world → view transform of a camera at `eye` looking at `target`: the camera
/// looks down −z, x is right and y is up (the component of `up` across the view direction).
fn view_transform(eye: DVec3, target: DVec3, up: DVec3) -> DAffine3 {
    let forward = (target - eye).normalize();
    let right = forward.cross(up).normalize();
    let up = right.cross(forward);
    DAffine3 {
        matrix3: DMat3::from_cols(
            DVec3::new(right.x, up.x, -forward.x),
            DVec3::new(right.y, up.y, -forward.y),
            DVec3::new(right.z, up.z, -forward.z),
        ),
        translation: DVec3::new(-eye.dot(right), -eye.dot(up), eye.dot(forward)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera::new(
            DVec3::new(0.3, 0.2, 4.0),
            DVec3::new(0.0, 0.1, 0.0),
            DVec3::Y,
            40.0,
            320,
            200,
        )
        .unwrap()
        .with_near(0.01)
        .unwrap()
    }

    #[test]
    fn target_projects_to_image_centre() {
        let cam = camera();
        let (px, depth) = cam
            .project(cam.view.transform_point3(DVec3::new(0.0, 0.1, 0.0)))
            .unwrap();
        assert!((px - DVec2::new(160.0, 100.0)).length() < 1e-9);
        assert!((depth - DVec3::new(0.3, 0.1, 4.0).length()).abs() < 1e-9);
    }

    #[test]
    fn up_is_up_on_screen_and_right_is_right() {
        let cam = Camera::new(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            60.0,
            100,
            100,
        )
        .unwrap()
        .with_near(0.01)
        .unwrap();
        let up = cam
            .project(cam.view.transform_point3(DVec3::new(0.0, 1.0, 0.0)))
            .unwrap()
            .0;
        let right = cam
            .project(cam.view.transform_point3(DVec3::new(1.0, 0.0, 0.0)))
            .unwrap()
            .0;
        assert!(up.y < 50.0 && (up.x - 50.0).abs() < 1e-9);
        assert!(right.x > 50.0 && (right.y - 50.0).abs() < 1e-9);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let cam = camera();
        let p = DVec3::new(0.4, -0.7, -3.0);
        let jac = cam.jacobian(p);
        let h = 1e-6;
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            let plus = cam.project(p + axis * h).unwrap().0;
            let minus = cam.project(p - axis * h).unwrap().0;
            let numeric = (plus - minus) / (2.0 * h);
            assert!(
                (numeric - jac.apply(axis)).length() < 1e-5,
                "{numeric} vs {}",
                jac.apply(axis)
            );
        }
    }

    #[test]
    fn an_eye_too_far_for_a_double_blames_the_distance_not_up() {
        let far = Camera::new(DVec3::X * 1e300, DVec3::ZERO, DVec3::Y, 40.0, 64, 48);
        let message = far.unwrap_err().to_string();
        assert!(
            message.starts_with("target") && message.contains("too far from camera.eye"),
            "{message}"
        );
        assert!(Camera::new(DVec3::X * 1e150, DVec3::ZERO, DVec3::Y, 40.0, 64, 48).is_ok());
    }

    #[test]
    fn a_field_of_view_below_the_narrowest_is_refused_with_its_range() {
        let with_fov = |fov| Camera::new(DVec3::Z, DVec3::ZERO, DVec3::Y, fov, 64, 48);
        assert!(with_fov(MIN_FOV_Y_DEGREES).is_ok());
        let message = with_fov(1e-300).unwrap_err().to_string();
        assert_eq!(
            message,
            "fov_y: 1e-300: the vertical field of view is in degrees, at least 0.001 and below 180"
        );
    }

    #[test]
    fn points_behind_the_near_plane_do_not_project() {
        let cam = camera();
        assert!(cam.project(DVec3::new(0.0, 0.0, 0.5)).is_none());
        assert!(cam.project(DVec3::new(0.0, 0.0, -0.001)).is_none());
        assert!(cam.project(DVec3::new(0.0, 0.0, f64::NAN)).is_none());
    }
}
