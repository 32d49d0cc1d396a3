//! The filmstrip: a side view of the scene (looking along +y, z up) at a few instants, the
//! colliders in grey, each body's front-facing boundary triangles painted back to front and
//! shaded by their normal. Hand-written SVG: no dependency, any browser opens it.

use std::collections::HashMap;
use std::fmt::Write as _;

use softfem::glam::{Vec2, Vec3};
use softfem::step::{Collider, Shape};

/// The boundary triangles of a tetrahedral mesh (faces of exactly one tet), wound outward for
/// positively oriented tets.
pub fn boundary(tets: &[[u32; 4]]) -> Vec<[u32; 3]> {
    let mut faces: HashMap<[u32; 3], ([u32; 3], u32)> = HashMap::new();
    for &[a, b, c, d] in tets {
        for face in [[a, c, b], [a, b, d], [a, d, c], [b, c, d]] {
            let mut key = face;
            key.sort_unstable();
            faces.entry(key).or_insert((face, 0)).1 += 1;
        }
    }
    let mut boundary: Vec<[u32; 3]> = faces
        .into_values()
        .filter(|&(_, count)| count == 1)
        .map(|(face, _)| face)
        .collect();
    boundary.sort_unstable();
    boundary
}

/// The scene at one instant.
pub struct Snapshot {
    time: f32,
    colliders: Vec<Collider<'static>>,
    bodies: Vec<Vec<Vec3>>,
}

/// Keeps the scene at `count` steps evenly spaced over the run.
pub struct Recorder {
    targets: Vec<usize>,
    snapshots: Vec<Snapshot>,
}

impl Recorder {
    /// Snapshots at steps `0, steps / (count - 1), ..., steps`.
    pub fn new(count: usize, steps: usize) -> Recorder {
        let last = count.max(2) - 1;
        Recorder {
            targets: (0..=last).map(|i| (i * steps + last / 2) / last).collect(),
            snapshots: Vec::new(),
        }
    }

    /// Offers the scene at `step` (time `time`, s); kept if it is one of the targets.
    pub fn offer(
        &mut self,
        step: usize,
        time: f32,
        colliders: &[Collider<'static>],
        bodies: &[Vec<Vec3>],
    ) {
        if self.targets.contains(&step) && self.snapshots.len() < self.targets.len() {
            self.snapshots.push(Snapshot {
                time,
                colliders: colliders.to_vec(),
                bodies: bodies.to_vec(),
            });
        }
    }
}

/// The panel size (px) and the world window it shows (m): x in `[X0, X1]`, z from `Z0` up
/// (1.75 m at this aspect ratio).
const PANEL: (f32, f32) = (330.0, 240.0);
const X0: f32 = -1.15;
const X1: f32 = 1.25;
const Z0: f32 = -0.1;
/// Body colours (RGB): the soft ball, the box, the stiff ball.
const COLOURS: [[f32; 3]; 3] = [[0.90, 0.35, 0.30], [0.30, 0.55, 0.90], [0.35, 0.75, 0.40]];

/// Screen coordinates (px) of the world point `x` in panel `k`.
fn screen(k: usize, x: Vec3) -> Vec2 {
    let scale = PANEL.0 / (X1 - X0);
    Vec2::new(
        k as f32 * PANEL.0 + (x.x - X0) * scale,
        PANEL.1 - (x.z - Z0) * scale,
    )
}

/// The convex hull of `points` (gift wrapping; a handful of points).
fn hull(points: &[Vec2]) -> Vec<Vec2> {
    let Some(start) = points
        .iter()
        .copied()
        .reduce(|a, b| if b.x < a.x { b } else { a })
    else {
        return Vec::new();
    };
    let mut hull = vec![start];
    let mut current = start;
    loop {
        let mut next = points[0];
        for &p in points {
            let turn = (next - current).perp_dot(p - current);
            if next == current
                || turn < 0.0
                || (turn == 0.0 && (p - current).length() > (next - current).length())
            {
                next = p;
            }
        }
        if next == start || hull.len() > points.len() {
            return hull;
        }
        hull.push(next);
        current = next;
    }
}

fn polygon(svg: &mut String, points: &[Vec2], fill: &str) {
    let list: Vec<String> = points
        .iter()
        .map(|p| format!("{:.1},{:.1}", p.x, p.y))
        .collect();
    let _ = writeln!(
        svg,
        r#"<polygon points="{}" fill="{fill}"/>"#,
        list.join(" ")
    );
}

/// Draws `collider` into panel `k`.
fn draw_collider(svg: &mut String, k: usize, collider: &Collider<'_>) {
    let scale = PANEL.0 / (X1 - X0);
    let grey = "#8a8f98";
    match collider.shape {
        Shape::HalfSpace => {
            let top = screen(k, collider.position).y;
            let _ = writeln!(
                svg,
                r#"<rect x="{:.1}" y="{top:.1}" width="{:.1}" height="{:.1}" fill="{grey}"/>"#,
                k as f32 * PANEL.0,
                PANEL.0,
                PANEL.1 - top
            );
        }
        Shape::Sphere { radius } => {
            let c = screen(k, collider.position);
            let _ = writeln!(
                svg,
                r#"<circle cx="{:.1}" cy="{:.1}" r="{:.1}" fill="{grey}"/>"#,
                c.x,
                c.y,
                radius * scale
            );
        }
        Shape::Capsule {
            half_length,
            radius,
        } => {
            let axis = collider.rotation * Vec3::Z * half_length;
            let (a, b) = (
                screen(k, collider.position - axis),
                screen(k, collider.position + axis),
            );
            let _ = writeln!(
                svg,
                r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{grey}" stroke-width="{:.1}" stroke-linecap="round"/>"#,
                a.x,
                a.y,
                b.x,
                b.y,
                2.0 * radius * scale
            );
        }
        Shape::Cuboid { half_extents: h } => {
            let corners: Vec<Vec2> = (0..8)
                .map(|i| {
                    let sign = |bit: usize| if i & bit == 0 { -1.0 } else { 1.0 };
                    let local = Vec3::new(h.x * sign(1), h.y * sign(2), h.z * sign(4));
                    screen(k, collider.position + collider.rotation * local)
                })
                .collect();
            polygon(svg, &hull(&corners), "#6d737d");
        }
        Shape::Custom(_) => {}
    }
}

/// The SVG filmstrip of the recorded snapshots; `surfaces[b]` the boundary of body `b`.
pub fn filmstrip(recorder: &Recorder, surfaces: &[Vec<[u32; 3]>]) -> String {
    let count = recorder.snapshots.len();
    let (width, height) = (PANEL.0 * count as f32, PANEL.1 + 24.0);
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}">"#
    );
    let _ = writeln!(
        svg,
        r##"<rect width="100%" height="100%" fill="#f4f1ea"/>"##
    );
    let light = Vec3::new(-0.4, -0.6, 0.7).normalize();
    for (k, snapshot) in recorder.snapshots.iter().enumerate() {
        for collider in &snapshot.colliders {
            draw_collider(&mut svg, k, collider);
        }
        // Front-facing triangles (normal towards the camera at -y), far ones first.
        let mut triangles: Vec<(f32, [Vec2; 3], String)> = Vec::new();
        for (b, (positions, surface)) in snapshot.bodies.iter().zip(surfaces).enumerate() {
            let colour = COLOURS[b % COLOURS.len()];
            for &[i, j, l] in surface {
                let [a, c, d] = [i, j, l].map(|v| positions[v as usize]);
                let normal = (c - a).cross(d - a).normalize_or_zero();
                if normal.y >= 0.0 {
                    continue;
                }
                let shade = 0.35 + 0.65 * normal.dot(light).max(0.0);
                let rgb = colour.map(|x| (255.0 * x * shade).round() as u8);
                let fill = format!("#{:02x}{:02x}{:02x}", rgb[0], rgb[1], rgb[2]);
                let depth = (a.y + c.y + d.y) / 3.0;
                triangles.push((depth, [a, c, d].map(|x| screen(k, x)), fill));
            }
        }
        triangles.sort_by(|p, q| q.0.total_cmp(&p.0));
        for (_, corners, fill) in &triangles {
            polygon(&mut svg, corners, fill);
        }
        let x = k as f32 * PANEL.0;
        let _ = writeln!(
            svg,
            r##"<text x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="14" fill="#333">t = {:.2} s</text>"##,
            x + 8.0,
            PANEL.1 + 17.0,
            snapshot.time
        );
        if k > 0 {
            let _ = writeln!(
                svg,
                r##"<line x1="{x:.1}" y1="0" x2="{x:.1}" y2="{height:.0}" stroke="#ccc"/>"##
            );
        }
    }
    svg.push_str("</svg>\n");
    svg
}
