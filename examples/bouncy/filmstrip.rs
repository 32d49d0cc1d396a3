//! An SVG filmstrip: the body's surface at a few instants, side by side, drawn the same way in
//! every panel so that height and shape compare at a glance.
//!
//! Each panel is an orthographic view from slightly above and to the side (the camera's
//! azimuth and elevation), with the ground as a grey square, the body's shadow cast straight
//! down onto it, and the front-facing surface triangles painted back to front (painter's
//! algorithm: correct for a single convex-ish body, which is what this scene drops) and shaded
//! by their normal (Lambert with an ambient term). Hand-written SVG: no dependency, and any
//! browser opens the file.

use std::fmt::Write as _;

use softfem::glam::{Vec2, Vec3};

/// The body at one instant.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// Simulated time (s).
    pub time: f64,
    /// Vertex positions (m).
    pub positions: Vec<Vec3>,
}

/// Keeps the frames closest to `count` instants evenly spaced over `[0, duration]`.
#[derive(Clone, Debug)]
pub struct Recorder {
    targets: Vec<f64>,
    tolerance: f64,
    snapshots: Vec<Option<Snapshot>>,
}

impl Recorder {
    /// Instants `0, duration / (count - 1), ..., duration` (just `0` if `count` is 1), filled
    /// by frames spaced `frame_interval` (s) apart.
    pub fn new(count: usize, duration: f64, frame_interval: f64) -> Recorder {
        let targets: Vec<f64> = match count {
            0 => Vec::new(),
            1 => vec![0.0],
            n => (0..n)
                .map(|i| duration * i as f64 / (n - 1) as f64)
                .collect(),
        };
        Recorder {
            snapshots: vec![None; targets.len()],
            targets,
            // A frame within half a frame interval of an instant is the nearest one.
            tolerance: frame_interval / 2.0 * (1.0 + 1e-9),
        }
    }

    /// Frames come `frame_interval` (s) apart from now on (a time step longer than the frame
    /// interval spaces them wider).
    pub fn set_frame_interval(&mut self, frame_interval: f64) {
        self.tolerance = frame_interval / 2.0 * (1.0 + 1e-9);
    }

    /// Offers the frame at `time`; it is kept for every still empty instant it is close to.
    pub fn offer(&mut self, time: f64, positions: &[Vec3]) {
        for (target, slot) in self.targets.iter().zip(&mut self.snapshots) {
            if slot.is_none() && (time - target).abs() <= self.tolerance {
                *slot = Some(Snapshot {
                    time,
                    positions: positions.to_vec(),
                });
            }
        }
    }

    /// The snapshots taken, in time order (instants no frame came close to are left out, as
    /// when a run stops early).
    pub fn snapshots(&self) -> Vec<Snapshot> {
        self.snapshots.iter().flatten().cloned().collect()
    }
}

/// An orthographic camera: `azimuth` turns the view about the vertical axis, `elevation` tilts
/// it down (radians). At `(0, 0)` it looks along `+y`, with `+x` to the right and `+z` up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Rotation about `z` (rad).
    pub azimuth: f32,
    /// Angle below the horizontal (rad).
    pub elevation: f32,
}

impl Default for Camera {
    fn default() -> Camera {
        Camera {
            azimuth: 30f32.to_radians(),
            elevation: 20f32.to_radians(),
        }
    }
}

impl Camera {
    /// `(right, up, forward)`: screen axes and viewing direction, orthonormal.
    fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let (sa, ca) = self.azimuth.sin_cos();
        let (se, ce) = self.elevation.sin_cos();
        let right = Vec3::new(ca, sa, 0.0);
        let forward = Vec3::new(-sa * ce, ca * ce, -se);
        (right, right.cross(forward), forward)
    }
}

/// What to draw.
#[derive(Clone, Copy, Debug)]
pub struct Filmstrip<'a> {
    /// The heading line.
    pub title: &'a str,
    /// A smaller second line.
    pub subtitle: &'a str,
    /// Boundary triangles, counter-clockwise seen from outside.
    pub triangles: &'a [[u32; 3]],
    /// The instants, one panel each.
    pub snapshots: &'a [Snapshot],
    /// The view.
    pub camera: Camera,
}

const PANEL_WIDTH: f32 = 220.0;
const PANEL_GAP: f32 = 12.0;
const MARGIN: f32 = 16.0;
const MIN_WIDTH: f32 = 760.0;
const TITLE_HEIGHT: f32 = 58.0;
const LABEL_HEIGHT: f32 = 30.0;
/// Jelly red (sRGB), scaled by the shading.
const BODY_COLOUR: Vec3 = Vec3::new(224.0, 52.0, 96.0);
const AMBIENT: f32 = 0.35;

impl Filmstrip<'_> {
    /// The picture as SVG text.
    pub fn to_svg(self) -> String {
        let (right, up, forward) = self.camera.basis();
        let project = |p: Vec3| Vec2::new(p.dot(right), p.dot(up));
        // Light from the upper left, on the camera's side.
        let light = (-forward + 1.2 * up - 0.6 * right).normalize();

        // The ground square under all instants, a little larger than the body's footprint.
        let (lo, hi) = self.snapshots.iter().flat_map(|s| s.positions.iter()).fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let (lo, hi) = if lo.x <= hi.x {
            (lo, hi)
        } else {
            (Vec3::ZERO, Vec3::ZERO)
        };
        let reach = (hi.x - lo.x).max(hi.y - lo.y).max(0.05) * 0.9;
        let centre = (lo + hi) / 2.0;
        let ground: Vec<Vec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|&(sx, sy)| Vec3::new(centre.x + sx * reach, centre.y + sy * reach, 0.0))
            .collect();

        // One scale for every panel, fitting the ground and the body at every instant.
        let screen_points = ground
            .iter()
            .copied()
            .chain(
                self.snapshots
                    .iter()
                    .flat_map(|s| s.positions.iter().copied()),
            )
            .map(project);
        let (smin, smax) = screen_points.fold(
            (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(p), hi.max(p)),
        );
        let extent = (smax - smin).max(Vec2::splat(1e-6));
        let scale = (PANEL_WIDTH - 2.0 * MARGIN) / extent.x;
        let panel_height = extent.y * scale + 2.0 * MARGIN;
        let to_panel = |p: Vec3| {
            let s = project(p);
            Vec2::new(
                MARGIN + (s.x - smin.x) * scale,
                MARGIN + (smax.y - s.y) * scale,
            )
        };

        let panels = self.snapshots.len().max(1) as f32;
        // Wide enough for the title even with a single panel.
        let width =
            (2.0 * MARGIN + panels * PANEL_WIDTH + (panels - 1.0) * PANEL_GAP).max(MIN_WIDTH);
        let height = TITLE_HEIGHT + panel_height + LABEL_HEIGHT + MARGIN;
        let mut svg = String::new();
        let _ = writeln!(
            svg,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}" font-family="Helvetica, Arial, sans-serif">"#
        );
        let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            svg,
            r#"<text x="{MARGIN}" y="26" font-size="17" font-weight="bold">{}</text>"#,
            escape(self.title)
        );
        let _ = writeln!(
            svg,
            r##"<text x="{MARGIN}" y="46" font-size="12" fill="#555">{}</text>"##,
            escape(self.subtitle)
        );

        for (i, snapshot) in self.snapshots.iter().enumerate() {
            let x0 = MARGIN + i as f32 * (PANEL_WIDTH + PANEL_GAP);
            let _ = writeln!(
                svg,
                r#"<g class="panel" transform="translate({x0:.1} {TITLE_HEIGHT})">"#
            );
            let _ = writeln!(
                svg,
                r##"<rect width="{PANEL_WIDTH}" height="{panel_height:.1}" fill="#f4f6f9" rx="6"/>"##
            );
            let _ = writeln!(
                svg,
                r##"<polygon class="ground" points="{}" fill="#d9d4c7" stroke="#a39d8c" stroke-width="1"/>"##,
                points(ground.iter().map(|&p| to_panel(p)))
            );
            // The shadow: every triangle flattened onto the ground, composited as one shape so
            // that overlaps do not darken.
            let _ = writeln!(svg, r#"<g class="shadow" opacity="0.22">"#);
            for tri in self.triangles {
                let corners =
                    tri.map(|v| snapshot.positions[v as usize] * Vec3::new(1.0, 1.0, 0.0));
                let _ = writeln!(
                    svg,
                    r#"<polygon points="{}"/>"#,
                    points(corners.iter().map(|&p| to_panel(p)))
                );
            }
            let _ = writeln!(svg, "</g>");

            let mut visible: Vec<(f32, [Vec3; 3], f32)> = self
                .triangles
                .iter()
                .filter_map(|tri| {
                    let [a, b, c] = tri.map(|v| snapshot.positions[v as usize]);
                    let normal = (b - a).cross(c - a).normalize_or_zero();
                    // Back faces (and degenerate ones) are hidden behind the front.
                    (normal.dot(forward) < 0.0).then(|| {
                        let depth = (a + b + c).dot(forward) / 3.0;
                        let shade = AMBIENT + (1.0 - AMBIENT) * normal.dot(light).max(0.0);
                        (depth, [a, b, c], shade)
                    })
                })
                .collect();
            visible.sort_by(|p, q| q.0.total_cmp(&p.0)); // farthest first
            let _ = writeln!(
                svg,
                r#"<g class="body" stroke-width="0.5" stroke-linejoin="round">"#
            );
            for (_, corners, shade) in &visible {
                let fill = BODY_COLOUR * *shade;
                let edge = fill * 0.82;
                let _ = writeln!(
                    svg,
                    r#"<polygon points="{}" fill="{}" stroke="{}"/>"#,
                    points(corners.iter().map(|&p| to_panel(p))),
                    rgb(fill),
                    rgb(edge)
                );
            }
            let _ = writeln!(svg, "</g>");
            if i == 0 {
                scale_bar(&mut svg, scale, panel_height);
            }
            let _ = writeln!(
                svg,
                r#"<text x="{:.1}" y="{:.1}" font-size="14" text-anchor="middle">t = {:.2} s</text>"#,
                PANEL_WIDTH / 2.0,
                panel_height + 20.0,
                snapshot.time
            );
            let _ = writeln!(svg, "</g>");
        }
        svg.push_str("</svg>\n");
        svg
    }
}

/// A horizontal bar of a round length in the panel's lower left corner. Horizontal screen
/// lengths are true lengths: the screen's right axis is horizontal and the view orthographic.
fn scale_bar(svg: &mut String, scale: f32, panel_height: f32) {
    let target = 0.25 * PANEL_WIDTH / scale; // about a quarter of the panel, in metres
    let length = [
        0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0,
    ]
    .into_iter()
    .rev()
    .find(|&l| l <= target)
    .unwrap_or(0.01);
    let (x, y) = (10.0, panel_height - 10.0);
    let label = if length < 1.0 {
        format!("{:.0} cm", length * 100.0)
    } else {
        format!("{length} m")
    };
    let _ = writeln!(
        svg,
        r##"<g class="scale"><line x1="{x}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#333" stroke-width="2"/><text x="{x}" y="{:.1}" font-size="10" fill="#333">{label}</text></g>"##,
        x + length * scale,
        y - 5.0
    );
}

fn points(corners: impl Iterator<Item = Vec2>) -> String {
    corners
        .map(|p| format!("{:.1},{:.1}", p.x, p.y))
        .collect::<Vec<_>>()
        .join(" ")
}

fn rgb(colour: Vec3) -> String {
    let [r, g, b] = colour
        .clamp(Vec3::ZERO, Vec3::splat(255.0))
        .round()
        .to_array();
    format!("#{:02x}{:02x}{:02x}", r as u8, g as u8, b as u8)
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Geometry;
    use crate::surface::Surface;

    #[test]
    fn camera_basis_is_orthonormal_and_right_handed() {
        let (r, u, f) = Camera::default().basis();
        for (a, b) in [(r, u), (u, f), (f, r)] {
            assert!(a.dot(b).abs() < 1e-6);
        }
        assert!(r.cross(u).dot(-f) > 0.999, "the camera looks along forward");
        assert!(u.z > 0.0 && f.z < 0.0, "looking down, up is up");
    }

    #[test]
    fn recorder_keeps_the_frames_nearest_to_evenly_spaced_instants() {
        let mut recorder = Recorder::new(3, 1.0, 0.1);
        for i in 0..=10 {
            recorder.offer(i as f64 * 0.1, &[Vec3::splat(i as f32)]);
        }
        let times: Vec<f64> = recorder.snapshots().iter().map(|s| s.time).collect();
        assert_eq!(times.len(), 3);
        assert!(
            (times[0]).abs() < 1e-12
                && (times[1] - 0.5).abs() < 1e-9
                && (times[2] - 1.0).abs() < 1e-9
        );
        assert_eq!(recorder.snapshots()[1].positions, [Vec3::splat(5.0)]);
        let mut one = Recorder::new(1, 3.0, 0.1);
        one.offer(0.0, &[]);
        one.offer(0.1, &[]);
        assert_eq!(one.snapshots().len(), 1);
    }

    /// The jelly cube at rest seen from above and to the side shows three of its six sides:
    /// `3 * 2 n^2` triangles, each painted once per panel.
    #[test]
    fn svg_has_one_panel_per_snapshot_and_shows_three_sides_of_a_cube() {
        let n = 3;
        let geometry = Geometry::jelly_cube(0.2, n, softfem::generate::BoxSplit::Kuhn6)
            .unwrap()
            .placed_above_ground(0.5);
        let surface = Surface::of_tets(&geometry.tets);
        let snapshots: Vec<Snapshot> = (0..4)
            .map(|i| Snapshot {
                time: 0.5 * i as f64,
                positions: geometry
                    .rest_positions
                    .iter()
                    .map(|p| *p - Vec3::new(0.0, 0.0, 0.15 * i as f32))
                    .collect(),
            })
            .collect();
        let strip = Filmstrip {
            title: "a <title> & more",
            subtitle: "sub",
            triangles: &surface.triangles,
            snapshots: &snapshots,
            camera: Camera::default(),
        };
        let svg = strip.to_svg();
        assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
        assert!(svg.ends_with("</svg>\n"));
        assert_eq!(svg.matches("class=\"panel\"").count(), 4);
        assert_eq!(svg.matches("class=\"ground\"").count(), 4);
        assert_eq!(svg.matches("class=\"scale\"").count(), 1);
        assert_eq!(svg.matches("<g").count(), svg.matches("</g>").count());
        assert!(svg.contains("a &lt;title&gt; &amp; more"));
        for label in ["t = 0.00 s", "t = 0.50 s", "t = 1.00 s", "t = 1.50 s"] {
            assert!(svg.contains(label), "{label}");
        }
        let body_polygons = svg.split("class=\"body\"").skip(1).map(|rest| {
            rest.split("</g>")
                .next()
                .unwrap()
                .matches("<polygon")
                .count()
        });
        for count in body_polygons {
            assert_eq!(count, 3 * 2 * n * n);
        }
        let shadow_polygons = svg.split("class=\"shadow\"").nth(1).unwrap();
        let shadow_polygons = shadow_polygons.split("</g>").next().unwrap();
        assert_eq!(shadow_polygons.matches("<polygon").count(), surface.len());
    }

    #[test]
    fn colours_are_clamped_hex() {
        assert_eq!(rgb(Vec3::new(255.0, 0.4, 300.0)), "#ff00ff");
        assert_eq!(rgb(Vec3::new(16.0, 32.0, -5.0)), "#102000");
    }
}
