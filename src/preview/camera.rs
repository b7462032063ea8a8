//! The preview camera: orthographic, looking along one axis of the scan's own frame, fitted
//! to the meshes' extent.
//!
//! "Front" for a scan is the side the scanner saw. Scanners (stereo rigs, structured light,
//! photogrammetry exports of face captures) write their meshes in the scanner's frame, whose
//! view axis is −Z with +Y up (OpenGL convention, and that of every face scan in
//! ../shared/data). So the default camera sits on the +Z side and looks along −Z with +Y up.
//! A scan in another frame (Z up, say) chooses its axis in the recipe's `[preview]` table.
//! Guessing the axis from the geometry (the mean normal of an open face mask points at the
//! scanner) fails on closed heads and busts, whose normals cancel, so we do not guess.
//! Orthographic, because the three panels are compared pixel by pixel and a scale bar only
//! means something without perspective.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A coordinate axis with a sign, as written in a recipe: "-z", "+y", ...
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Axis {
    #[serde(rename = "+x")]
    PosX,
    #[serde(rename = "-x")]
    NegX,
    #[serde(rename = "+y")]
    PosY,
    #[serde(rename = "-y")]
    NegY,
    #[serde(rename = "+z")]
    PosZ,
    #[serde(rename = "-z")]
    NegZ,
}

impl Axis {
    pub fn vector(self) -> DVec3 {
        match self {
            Axis::PosX => DVec3::X,
            Axis::NegX => DVec3::NEG_X,
            Axis::PosY => DVec3::Y,
            Axis::NegY => DVec3::NEG_Y,
            Axis::PosZ => DVec3::Z,
            Axis::NegZ => DVec3::NEG_Z,
        }
    }

    /// The default "up" for a view along this axis: +Y, or +Z when looking along Y.
    pub fn default_up(self) -> Axis {
        match self {
            Axis::PosY | Axis::NegY => Axis::PosZ,
            _ => Axis::PosY,
        }
    }
}

/// A pixel rectangle of the image the camera draws into.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viewport {
    pub x: f64,
    pub y: f64,
    pub width: f64,
    pub height: f64,
}

/// An orthographic camera. Image rows grow downwards: a point `up` of the centre has a
/// smaller row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// The model point drawn at the viewport's centre.
    pub centre: DVec3,
    /// Unit vectors: the direction the camera looks along, image right and image up.
    pub forward: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    /// Pixels per model unit.
    pub scale: f64,
    pub viewport: Viewport,
}

impl Camera {
    /// A camera looking along `view` with `up` towards the image top.
    /// `None` if `up` is parallel to `view`.
    pub fn looking(
        view: Axis,
        up: Axis,
        centre: DVec3,
        scale: f64,
        viewport: Viewport,
    ) -> Option<Camera> {
        let forward = view.vector();
        let up = up.vector();
        let right = forward.cross(up);
        if right.length_squared() < 0.5 {
            return None;
        }
        Some(Camera {
            centre,
            forward,
            right,
            up,
            scale,
            viewport,
        })
    }

    /// Frames the points: the camera looks at the centre of their projected extent and
    /// scales it to fill the viewport, less `margin` (a fraction) on every side. `None`
    /// for no points, non-finite points or `up` parallel to `view`.
    pub fn fit<'a>(
        points: impl IntoIterator<Item = &'a DVec3>,
        view: Axis,
        up: Axis,
        viewport: Viewport,
        margin: f64,
    ) -> Option<Camera> {
        let mut camera = Camera::looking(view, up, DVec3::ZERO, 1.0, viewport)?;
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for &p in points {
            let q = DVec3::new(p.dot(camera.right), p.dot(camera.up), p.dot(camera.forward));
            lo = lo.min(q);
            hi = hi.max(q);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let mid = (lo + hi) * 0.5;
        camera.centre = camera.right * mid.x + camera.up * mid.y + camera.forward * mid.z;
        let (ex, ey) = (hi.x - lo.x, hi.y - lo.y);
        let usable = 1.0 - 2.0 * margin.clamp(0.0, 0.45);
        let sx = viewport.width * usable / ex;
        let sy = viewport.height * usable / ey;
        // A flat or point-like extent in one direction: the other decides (1 if both).
        camera.scale = match (ex > 0.0, ey > 0.0) {
            (true, true) => sx.min(sy),
            (true, false) => sx,
            (false, true) => sy,
            (false, false) => 1.0,
        };
        Some(camera)
    }

    /// Image position (column, row, in pixels, continuous) and depth (larger = farther).
    #[inline]
    pub fn project(&self, p: DVec3) -> DVec3 {
        let d = p - self.centre;
        DVec3::new(
            self.viewport.x + 0.5 * self.viewport.width + d.dot(self.right) * self.scale,
            self.viewport.y + 0.5 * self.viewport.height - d.dot(self.up) * self.scale,
            d.dot(self.forward),
        )
    }

    /// The same camera drawing into an image `factor` times larger (supersampling).
    pub fn scaled(&self, factor: f64) -> Camera {
        Camera {
            scale: self.scale * factor,
            viewport: Viewport {
                x: self.viewport.x * factor,
                y: self.viewport.y * factor,
                width: self.viewport.width * factor,
                height: self.viewport.height * factor,
            },
            ..*self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn viewport() -> Viewport {
        Viewport {
            x: 0.0,
            y: 0.0,
            width: 100.0,
            height: 100.0,
        }
    }

    #[test]
    fn default_front_view_has_x_right_y_up_z_towards_viewer() {
        let c = Camera::looking(Axis::NegZ, Axis::PosY, DVec3::ZERO, 10.0, viewport()).unwrap();
        assert_eq!((c.right, c.up), (DVec3::X, DVec3::Y));
        let p = c.project(DVec3::new(1.0, 2.0, 3.0));
        // 1 to the right, 2 up (rows grow downwards); nearer (+z) has smaller depth.
        assert_eq!(p, DVec3::new(60.0, 30.0, -3.0));
        assert!(Camera::looking(Axis::NegZ, Axis::PosZ, DVec3::ZERO, 1.0, viewport()).is_none());
        assert_eq!(Axis::NegY.default_up(), Axis::PosZ);
    }

    #[test]
    fn fit_centres_and_fills_the_viewport() {
        let pts = [DVec3::new(2.0, 1.0, 0.0), DVec3::new(6.0, 3.0, 5.0)];
        let c = Camera::fit(&pts, Axis::NegZ, Axis::PosY, viewport(), 0.1).unwrap();
        // Width 4 is the larger extent: 4 units → 80 pixels.
        assert!((c.scale - 20.0).abs() < 1e-12);
        let a = c.project(pts[0]);
        let b = c.project(pts[1]);
        assert!((a.x - 10.0).abs() < 1e-12 && (b.x - 90.0).abs() < 1e-12);
        assert!((a.y - 70.0).abs() < 1e-12 && (b.y - 30.0).abs() < 1e-12);
        assert!(Camera::fit(&[], Axis::NegZ, Axis::PosY, viewport(), 0.1).is_none());
        let nan = [DVec3::new(f64::NAN, 0.0, 0.0)];
        assert!(Camera::fit(&nan, Axis::NegZ, Axis::PosY, viewport(), 0.1).is_none());
    }
}
