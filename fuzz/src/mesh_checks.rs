//! Mesh construction and every mesh kernel on arbitrary indices, rest shapes and positions
//! (included once per precision by `lib.rs`).
//!
//! Promises checked (`src/mesh/*.rs`, `src/error.rs`):
//! * nothing panics;
//! * a constructor's error is the first offender in the documented order (rest buffer length,
//!   first non-finite rest vertex, first out-of-range corner, first inverted or degenerate
//!   element), checked against an independent scan; inverted and degenerate elements against
//!   an f64 classification of each rest element wherever it is clear-cut (far from the
//!   `DEGENERACY_RATIO` threshold), and against the element API (`TetRest::new`, ...);
//! * a kernel's error is one the documented checks allow, in their order: the clamp threshold
//!   (`ClampThreshold`, outside `(0, 1]`), the positions (length, first non-finite vertex), the
//!   output length and the deformation range (`DeformationRange`: the first element with an
//!   entry of `F` beyond `Material::deformation_limit`, from an f64 `F`; elements within this
//!   precision's error in `F` of the limit may go either way; the kernels differ in which of
//!   the last two they check first); for `lumped_masses` the density, the length and the mass
//!   range (`MassRange`: the first element whose share is not a normal number at most
//!   `Real::MAX / element count`). On error the output buffer is bit-for-bit unchanged;
//! * on success, outputs are finite when the inputs are in the documented range: moduli and
//!   densities of physical size on a body of physical size (coordinates in `[-8, 8]`), clamp
//!   thresholds in `[0.05, 1]`, and deformation gradients (computed here in f64) with
//!   `|F| <= 1e3` (`|F| <= 10` and `|det F|` clear of zero for the neo-Hookean barrier model);
//!   and for StVK and stable neo-Hookean, documented finite for every `F` within their
//!   deformation limit, with any valid moduli: per-element stresses always, energies on a body
//!   of physical size;
//! * `elastic_energy` is the in-order sum of `element_energies`.

use super::NAME;
use super::precision as draw_real;
use super::sf::element::{DEGENERACY_RATIO, TetRest, TriRest, TriangleStVK};
use super::sf::material::{Material, NeoHookean, StVK, StableNeoHookean};
use super::sf::mesh::{MembraneMesh, TetMesh, TriMesh};
use super::sf::types::{Mat3, Real, Vec2, Vec3};
use super::sf::{Buffer, ElementError, MeshError};
use crate::Draw;

/// Runs the mesh checks on one fuzzer input.
pub fn check(data: &[u8]) {
    let mut draw = Draw::new(data);
    match draw.up_to(2) {
        0 => tet_mesh(&mut draw),
        1 => tri_mesh(&mut draw),
        _ => membrane_mesh(&mut draw),
    }
}

/// A position type: `Vec2` (2D triangles) or `Vec3`.
trait Point: Copy + core::fmt::Debug {
    const DIM: usize;
    fn from_coords(c: [Real; 3]) -> Self;
    /// The coordinates in f64 (the third is 0 in 2D).
    fn wide(self) -> [f64; 3];
    fn finite(self) -> bool;
    fn bits(self) -> [u64; 3];
}

impl Point for Vec2 {
    const DIM: usize = 2;
    fn from_coords([x, y, _]: [Real; 3]) -> Self {
        Vec2::new(x, y)
    }
    fn wide(self) -> [f64; 3] {
        [self.x as f64, self.y as f64, 0.0]
    }
    fn finite(self) -> bool {
        self.is_finite()
    }
    fn bits(self) -> [u64; 3] {
        [self.x.to_bits().into(), self.y.to_bits().into(), 0]
    }
}

impl Point for Vec3 {
    const DIM: usize = 3;
    fn from_coords([x, y, z]: [Real; 3]) -> Self {
        Vec3::new(x, y, z)
    }
    fn wide(self) -> [f64; 3] {
        [self.x as f64, self.y as f64, self.z as f64]
    }
    fn finite(self) -> bool {
        self.is_finite()
    }
    fn bits(self) -> [u64; 3] {
        [
            self.x.to_bits().into(),
            self.y.to_bits().into(),
            self.z.to_bits().into(),
        ]
    }
}

fn bits_of<P: Point>(points: &[P]) -> Vec<[u64; 3]> {
    points.iter().map(|p| p.bits()).collect()
}

fn real_bits(values: &[Real]) -> Vec<u64> {
    values.iter().map(|x| x.to_bits().into()).collect()
}

/// How the coordinates of a buffer are drawn.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Coordinates {
    /// A coarse grid: coplanar and coincident points are common.
    Coarse,
    /// A fine grid in `[-8, 8)`.
    Fine,
    /// Mostly the fine grid, some coordinates anything (NaN, inf, huge, subnormal).
    Mixed,
    /// Every coordinate anything.
    Wild,
}

impl Coordinates {
    fn draw(draw: &mut Draw<'_>) -> Self {
        match draw.up_to(7) {
            0 | 1 => Coordinates::Coarse,
            2..=4 => Coordinates::Fine,
            5 | 6 => Coordinates::Mixed,
            _ => Coordinates::Wild,
        }
    }

    fn coordinate(self, draw: &mut Draw<'_>) -> Real {
        match self {
            Coordinates::Coarse => draw_real::coarse(draw),
            Coordinates::Fine => draw_real::grid(draw, 1.0),
            Coordinates::Mixed if draw.chance(16) => draw_real::wild(draw),
            Coordinates::Mixed => draw_real::grid(draw, 1.0),
            Coordinates::Wild => draw_real::wild(draw),
        }
    }

    fn point<P: Point>(self, draw: &mut Draw<'_>) -> P {
        P::from_coords([
            self.coordinate(draw),
            self.coordinate(draw),
            if P::DIM == 3 {
                self.coordinate(draw)
            } else {
                0.0
            },
        ])
    }
}

/// A length near `len`: usually `len`, sometimes one off (or zero).
fn length_near(draw: &mut Draw<'_>, len: usize) -> usize {
    match draw.up_to(63) {
        0 => len + 1,
        1 => len.saturating_sub(1),
        2 => 0,
        _ => len,
    }
}

/// Rest positions and elements with `N` corners, indices mostly in range, optionally with every
/// element oriented positively by the harness (from an f64 signed measure) so that most meshes
/// are valid.
fn draw_mesh<P: Point, const N: usize>(
    draw: &mut Draw<'_>,
    signed_measure: fn(&[[f64; 3]; N]) -> f64,
) -> (Vec<P>, Vec<[u32; N]>) {
    let coordinates = Coordinates::draw(draw);
    let vertex_count = draw.index(12);
    let rest: Vec<P> = (0..vertex_count).map(|_| coordinates.point(draw)).collect();
    let element_count = draw.index(9);
    let orient = draw.chance(224);
    let elements = (0..element_count)
        .map(|_| {
            let mut corners = [0u32; N];
            for corner in &mut corners {
                *corner = match draw.up_to(63) {
                    0 => draw.u32(),
                    1 => vertex_count as u32,
                    _ => draw.index(vertex_count.saturating_sub(1)) as u32,
                };
            }
            if orient && gather_wide(&rest, &corners).is_some_and(|x| signed_measure(&x) < 0.0) {
                corners.swap(1, 2);
            }
            corners
        })
        .collect();
    (rest, elements)
}

fn gather_wide<P: Point, const N: usize>(
    points: &[P],
    corners: &[u32; N],
) -> Option<[[f64; 3]; N]> {
    let mut out = [[0.0; 3]; N];
    for (slot, &i) in out.iter_mut().zip(corners) {
        *slot = points.get(i as usize)?.wide();
    }
    Some(out)
}

fn gather<P: Point, const N: usize>(points: &[P], corners: &[u32; N]) -> Option<[P; N]> {
    let mut out = [points.first().copied()?; N];
    for (slot, &i) in out.iter_mut().zip(corners) {
        *slot = *points.get(i as usize)?;
    }
    Some(out)
}

/// The constructor error an independent scan expects before any element is looked at: rest
/// buffer length, first non-finite rest position, first out-of-range corner.
fn expected_prefix_error<P: Point, const N: usize>(
    rest: &[P],
    elements: &[[u32; N]],
    rest_len: usize,
) -> Option<MeshError> {
    if rest_len != elements.len() {
        return Some(MeshError::LengthMismatch {
            buffer: Buffer::RestData,
            expected: elements.len(),
            actual: rest_len,
        });
    }
    for (vertex, p) in rest.iter().enumerate() {
        if !p.wide().iter().all(|c| c.is_finite()) {
            return Some(MeshError::NonFiniteRestPosition { vertex });
        }
    }
    for (element, corners) in elements.iter().enumerate() {
        for (corner, &index) in corners.iter().enumerate() {
            if index as usize >= rest.len() {
                return Some(MeshError::IndexOutOfRange {
                    element,
                    corner: corner as u8,
                    index,
                    vertex_count: rest.len(),
                });
            }
        }
    }
    None
}

/// An element's rest shape as an f64 computation sees it, where the answer is clear-cut.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Class {
    Good,
    Inverted,
    Degenerate,
    /// Within a factor 4 of the threshold, or at a scale where this precision's rounding of
    /// `L^3` or `Dm^-1` decides.
    Unclear,
}

/// Classifies a signed measure (volume or area) against `L^power` (`L` the longest edge, `power`
/// 3 or 2) as `element::check_measure` documents: degenerate when
/// `|measure| <= DEGENERACY_RATIO * L^power`, inverted when negative.
fn classify(measure: f64, longest: f64, power: i32) -> Class {
    if measure == 0.0 {
        return Class::Degenerate;
    }
    // Far from both ends of the range, so that L^3, the volume and Dm^-1 are all comfortably
    // representable in this precision.
    let limit = (Real::MAX as f64).powf(0.2);
    if !(longest > 1.0 / limit && longest < limit) {
        return Class::Unclear;
    }
    let threshold = DEGENERACY_RATIO as f64 * longest.powi(power);
    if measure.abs() < threshold / 4.0 {
        Class::Degenerate
    } else if measure.abs() <= 4.0 * threshold {
        Class::Unclear
    } else if measure < 0.0 {
        Class::Inverted
    } else {
        Class::Good
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn longest_edge<const N: usize>(x: &[[f64; 3]; N]) -> f64 {
    let mut longest: f64 = 0.0;
    for i in 0..N {
        for j in i + 1..N {
            longest = longest.max(dot(sub(x[j], x[i]), sub(x[j], x[i])).sqrt());
        }
    }
    longest
}

fn tet_volume(x: &[[f64; 3]; 4]) -> f64 {
    let (e1, e2, e3) = (sub(x[1], x[0]), sub(x[2], x[0]), sub(x[3], x[0]));
    dot(e1, cross(e2, e3)) / 6.0
}

fn tri_area(x: &[[f64; 3]; 3]) -> f64 {
    let (e1, e2) = (sub(x[1], x[0]), sub(x[2], x[0]));
    (e1[0] * e2[1] - e1[1] * e2[0]) / 2.0
}

fn membrane_area(x: &[[f64; 3]; 3]) -> f64 {
    let n = cross(sub(x[1], x[0]), sub(x[2], x[0]));
    dot(n, n).sqrt() / 2.0
}

/// The element-level verdict as a class.
fn element_class(result: &Result<impl Sized, ElementError>) -> Class {
    match result {
        Ok(_) => Class::Good,
        Err(ElementError::Inverted) => Class::Inverted,
        Err(ElementError::Degenerate) => Class::Degenerate,
        Err(other) => panic!("{NAME}: element rest data of finite positions failed with {other:?}"),
    }
}

/// Checks a mesh constructor's result against the independent scan and the element API.
/// `element` builds one element's rest data through the element API; `measure` and `scale_power`
/// classify it in f64. Returns whether the mesh is valid.
fn check_construction<P: Point, R: PartialEq + core::fmt::Debug + Copy, const N: usize>(
    rest: &[P],
    elements: &[[u32; N]],
    rest_len: usize,
    outcome: Result<(), MeshError>,
    rest_data: &[R],
    element: impl Fn([P; N]) -> Result<R, ElementError>,
    measure: fn(&[[f64; 3]; N]) -> f64,
    scale_power: i32,
) -> bool {
    if let Some(expected) = expected_prefix_error(rest, elements, rest_len) {
        crate::trace(|| {
            format!("{NAME} construction: prefix {expected:?}")
                .split(' ')
                .take(4)
                .collect::<Vec<_>>()
                .join(" ")
        });
        assert_eq!(
            outcome,
            Err(expected),
            "{NAME}: constructor must report the first offender {expected:?}"
        );
        return false;
    }
    // Every index is in range and every rest position finite: classify each element.
    let mut first_failure = None;
    for (index, corners) in elements.iter().enumerate() {
        let (Some(x), Some(wide)) = (gather(rest, corners), gather_wide(rest, corners)) else {
            unreachable!("indices were checked in range");
        };
        let result = element(x);
        let by_element_api = element_class(&result);
        let independent = classify(measure(&wide), longest_edge(&wide), scale_power);
        if independent != Class::Unclear {
            assert_eq!(
                by_element_api, independent,
                "{NAME}: element {index} at rest {wide:?}: the element API says {by_element_api:?}, \
                 an f64 computation {independent:?}"
            );
        }
        match result {
            Err(error) if first_failure.is_none() => {
                first_failure = Some(match error {
                    ElementError::Inverted => MeshError::InvertedElement { element: index },
                    _ => MeshError::DegenerateElement { element: index },
                });
            }
            Ok(data) if first_failure.is_none() && outcome.is_ok() => {
                assert_eq!(
                    rest_data[index], data,
                    "{NAME}: the mesh's rest data of element {index} differs from the element API's"
                );
            }
            _ => {}
        }
    }
    crate::trace(|| {
        format!("{NAME} construction: {first_failure:?}")
            .split(' ')
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    });
    match first_failure {
        Some(expected) => {
            assert_eq!(
                outcome,
                Err(expected),
                "{NAME}: constructor must name the first bad element"
            );
            false
        }
        None => {
            assert_eq!(outcome, Ok(()), "{NAME}: constructor refused a valid mesh");
            true
        }
    }
}

/// The kernel error an independent scan expects for a deformed position buffer.
fn expected_positions_error<P: Point>(vertex_count: usize, positions: &[P]) -> Option<MeshError> {
    if positions.len() != vertex_count {
        return Some(MeshError::LengthMismatch {
            buffer: Buffer::Positions,
            expected: vertex_count,
            actual: positions.len(),
        });
    }
    positions
        .iter()
        .position(|p| !p.finite())
        .map(|vertex| MeshError::NonFinitePosition { vertex })
}

fn expected_output_error(buffer: Buffer, expected: usize, actual: usize) -> Option<MeshError> {
    (expected != actual).then_some(MeshError::LengthMismatch {
        buffer,
        expected,
        actual,
    })
}

/// Deformed positions: the rest shape plus a displacement of some amplitude, sometimes wild
/// coordinates, a NaN, or the wrong length.
fn draw_positions<P: Point>(draw: &mut Draw<'_>, rest: &[P]) -> Vec<P> {
    let amplitude: Real = [0.0, 1e-3, 0.1, 0.5, 2.0, 1e3][draw.index(5)];
    let wild = draw.chance(24);
    let mut positions: Vec<P> = rest
        .iter()
        .map(|p| {
            let w = p.wide();
            let mut c = [0.0 as Real; 3];
            for (k, slot) in c.iter_mut().enumerate() {
                *slot = if wild && draw.chance(64) {
                    draw_real::wild(draw)
                } else {
                    w[k] as Real + draw_real::grid(draw, amplitude / 8.0)
                };
            }
            P::from_coords(c)
        })
        .collect();
    if draw.chance(12) && !positions.is_empty() {
        let vertex = draw.index(positions.len() - 1);
        let nan = [Real::NAN, Real::INFINITY, Real::NEG_INFINITY][draw.index(2)];
        let mut c = [0.0 as Real; 3];
        for (k, slot) in c.iter_mut().enumerate() {
            *slot = positions[vertex].wide()[k] as Real;
        }
        c[draw.index(P::DIM - 1)] = nan;
        positions[vertex] = P::from_coords(c);
    }
    let len = length_near(draw, positions.len());
    positions.resize(len, P::from_coords([0.0; 3]));
    positions
}

/// An output buffer of `len` entries (sometimes the wrong length) holding finite values, so that
/// "unchanged" and "added into" are both observable.
fn draw_vectors<P: Point>(draw: &mut Draw<'_>, len: usize) -> Vec<P> {
    let len = length_near(draw, len);
    (0..len)
        .map(|_| {
            P::from_coords([
                draw_real::grid(draw, 1.0),
                draw_real::grid(draw, 1.0),
                draw_real::grid(draw, 1.0),
            ])
        })
        .collect()
}

fn draw_reals(draw: &mut Draw<'_>, len: usize) -> Vec<Real> {
    let len = length_near(draw, len);
    (0..len).map(|_| draw_real::grid(draw, 1.0)).collect()
}

/// Checks an `add_*`/write kernel: `result` against the expected error, `after` against
/// `before` (unchanged on error), finiteness on success when `finite_expected`.
fn check_kernel<T: PartialEq + core::fmt::Debug>(
    kernel: (&str, &str),
    result: Result<(), MeshError>,
    expected: Option<MeshError>,
    before: &T,
    after: &T,
    all_finite: bool,
    finite_expected: bool,
) {
    let (kernel, model) = kernel;
    crate::trace(|| {
        let outcome = match (&expected, finite_expected) {
            (Some(_), _) => "error",
            (None, true) => "ok, finiteness asserted",
            (None, false) => "ok, outside the documented range",
        };
        format!("{NAME} {kernel} {model}: {outcome}")
    });
    match expected {
        Some(error) => {
            assert_eq!(
                result,
                Err(error),
                "{NAME}: {kernel} ({model}) must report {error:?}"
            );
            assert_eq!(
                before, after,
                "{NAME}: {kernel} ({model}) changed its output on error"
            );
        }
        None => {
            assert_eq!(
                result,
                Ok(()),
                "{NAME}: {kernel} ({model}) refused valid input"
            );
            if finite_expected {
                assert!(
                    all_finite,
                    "{NAME}: {kernel} ({model}) gave a non-finite output in the documented range"
                );
            }
        }
    }
}

/// A material's parameters: of physical size (the documented range) or anything the
/// constructor accepts.
fn draw_lame(draw: &mut Draw<'_>) -> (Real, Real, bool) {
    if draw.chance(32) {
        (draw_real::wild(draw), draw_real::wild(draw), false)
    } else {
        let e = draw_real::magnitude(draw, 2, 9);
        let nu = draw_real::poisson(draw);
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        (lambda, e / (2.0 * (1.0 + nu)), true)
    }
}

/// A density (kg/m^3): physical, or anything.
fn draw_density(draw: &mut Draw<'_>) -> (Real, bool) {
    if draw.chance(32) {
        (draw_real::wild(draw), false)
    } else {
        (draw_real::magnitude(draw, -2, 4), true)
    }
}

/// `lumped` (corners per element `corners`, rest measures `measures`) with a drawn density:
/// the documented checks in order (density, masses length, each element's mass share), the
/// output unchanged on error, and finite masses for a physical density on a body of physical
/// size (`rest_physical`).
fn check_masses(
    name: &str,
    draw: &mut Draw<'_>,
    vertex_count: usize,
    corners: usize,
    measures: &[Real],
    rest_physical: bool,
    lumped: impl Fn(Real, &mut [Real]) -> Result<(), MeshError>,
) {
    let (density, physical) = draw_density(draw);
    let mut masses = draw_reals(draw, vertex_count);
    let before = real_bits(&masses);
    let result = lumped(density, &mut masses);
    let density_check =
        Check::Known((!(density > 0.0 && density.is_finite())).then_some(MeshError::Density));
    let length_check = Check::Known(expected_output_error(
        Buffer::Masses,
        vertex_count,
        masses.len(),
    ));
    let scan = ElementScan::masses(density, corners, measures);
    let ok = masses.iter().all(|m| m.is_finite() && *m >= 0.0);
    check_with(
        name,
        "",
        result,
        &acceptable(
            &[density_check, length_check, Check::Deformation],
            false,
            &scan,
        ),
        &before,
        &real_bits(&masses),
        ok,
        physical && rest_physical,
    );
}

/// Whether every rest coordinate lies on the grid of `Coordinates::Fine` (multiples of `1/4096`
/// in `[-8, 8]`): a body of physical size, whose volumes, masses, energies and forces are far
/// from overflow. (Finite but astronomical rest shapes are valid meshes whose energies may
/// overflow, which no kernel promises otherwise.)
fn physical_size<P: Point>(rest: &[P]) -> bool {
    rest.iter()
        .flat_map(|p| p.wide())
        .all(|c| c.abs() <= 8.0 && (c * 4096.0).fract() == 0.0)
}

/// `(|Ds|_F, |Dm^-1|_F)` of a tetrahedron in f64.
fn edge_and_inverse_norms(rest: &[[f64; 3]; 4], deformed: &[[f64; 3]; 4]) -> (f64, f64) {
    let frobenius = |m: [[f64; 3]; 3]| m.iter().flatten().map(|e| e * e).sum::<f64>().sqrt();
    let ds = [
        sub(deformed[1], deformed[0]),
        sub(deformed[2], deformed[0]),
        sub(deformed[3], deformed[0]),
    ];
    // With deformed corners at the origin and the unit axes, Ds = I and F = Dm^-1.
    let axes = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    (frobenius(ds), frobenius(tet_gradient(rest, &axes)))
}

/// The deformation gradient of a tetrahedron in f64: `Ds Dm^-1` (columns are edges).
fn tet_gradient(rest: &[[f64; 3]; 4], deformed: &[[f64; 3]; 4]) -> [[f64; 3]; 3] {
    let dm = [
        sub(rest[1], rest[0]),
        sub(rest[2], rest[0]),
        sub(rest[3], rest[0]),
    ];
    let ds = [
        sub(deformed[1], deformed[0]),
        sub(deformed[2], deformed[0]),
        sub(deformed[3], deformed[0]),
    ];
    // Dm^-1 = adj(Dm) / det: its rows are the cross products of Dm's columns over det.
    let det = dot(dm[0], cross(dm[1], dm[2]));
    let rows = [
        cross(dm[1], dm[2]),
        cross(dm[2], dm[0]),
        cross(dm[0], dm[1]),
    ];
    // F column j = sum_k Ds column k * (Dm^-1)_{kj} = sum_k ds[k] * rows[k][j] / det.
    let mut f = [[0.0; 3]; 3];
    for (j, column) in f.iter_mut().enumerate() {
        for (i, entry) in column.iter_mut().enumerate() {
            *entry = (0..3).map(|k| ds[k][i] * rows[k][j]).sum::<f64>() / det;
        }
    }
    f
}

/// `|F|_F` from the metrics: `|F|_F^2 = tr(G^-1 g)` with `G`, `g` the rest and deformed Gram
/// matrices of the edges (frame-free, so it serves 2D triangles and membranes alike).
///
/// Each set of edges is scaled by its largest coordinate first, and the norm scaled back: the
/// metrics of wild positions (edges of `1e153` in f64) overflow, and `c p - 2 b q + a r` of
/// overflowed terms is `-inf` or NaN, never the huge `|F|` it stands for (a fuzz input once made
/// it `-inf`, clamped to a gradient of 0, and so asserted finite output for a body stretched
/// `1e152` times).
fn triangle_gradient_norm(rest: &[[f64; 3]; 3], deformed: &[[f64; 3]; 3]) -> f64 {
    let largest = |u: [f64; 3], v: [f64; 3]| {
        u.iter().chain(&v).fold(
            0.0f64,
            |m, e| if e.is_nan() { f64::NAN } else { m.max(e.abs()) },
        )
    };
    let scaled = |u: [f64; 3], by: f64| [u[0] / by, u[1] / by, u[2] / by];
    let (r1, r2) = (sub(rest[1], rest[0]), sub(rest[2], rest[0]));
    let (d1, d2) = (sub(deformed[1], deformed[0]), sub(deformed[2], deformed[0]));
    let (rest_scale, deformed_scale) = (largest(r1, r2), largest(d1, d2));
    if !(deformed_scale.is_finite() && rest_scale.is_finite() && rest_scale > 0.0) {
        return f64::INFINITY;
    }
    if deformed_scale == 0.0 {
        return 0.0;
    }
    let (r1, r2) = (scaled(r1, rest_scale), scaled(r2, rest_scale));
    let (d1, d2) = (scaled(d1, deformed_scale), scaled(d2, deformed_scale));
    let (a, b, c) = (dot(r1, r1), dot(r1, r2), dot(r2, r2));
    let (p, q, r) = (dot(d1, d1), dot(d1, d2), dot(d2, d2));
    // G^-1 = [c -b; -b a] / (ac - b^2), of the scaled edges: every term below is at most 18.
    let squared = (c * p - 2.0 * b * q + a * r) / (a * c - b * b);
    // NaN (a degenerate rest metric) must not be taken for a small gradient: `max` would drop it.
    if squared.is_nan() {
        f64::INFINITY
    } else {
        squared.max(0.0).sqrt() * (deformed_scale / rest_scale)
    }
}

fn tet_mesh(draw: &mut Draw<'_>) {
    let (rest, tets) = draw_mesh::<Vec3, 4>(draw, tet_volume);
    let rest_len = length_near(draw, tets.len());
    let mut rest_data = vec![TetRest::default(); rest_len];
    let outcome = TetMesh::new(&rest, &tets, &mut rest_data).map(|_| ());
    let valid = check_construction(
        &rest,
        &tets,
        rest_len,
        outcome,
        &rest_data,
        TetRest::new,
        tet_volume,
        3,
    );
    if !valid {
        return;
    }
    let mesh = match TetMesh::new(&rest, &tets, &mut rest_data) {
        Ok(mesh) => mesh,
        Err(error) => panic!("{NAME}: a second construction of the same mesh failed: {error:?}"),
    };
    let n = rest.len();
    let rest_physical = physical_size(&rest);
    let volumes: Vec<Real> = mesh.rest().iter().map(|r| r.volume).collect();
    check_masses(
        "TetMesh::lumped_masses",
        draw,
        n,
        4,
        &volumes,
        rest_physical,
        |density, masses| mesh.lumped_masses(density, masses),
    );

    for _ in 0..=draw.up_to(1) {
        let positions = draw_positions(draw, &rest);
        // The documented range, from an f64 computation of every element's F: the largest
        // |F|_F, and whether every |det F| is clear of zero by more than this precision's
        // error in det F. That error: F itself is off by about
        // delta = 8 eps |Ds| |Dm^-1| (the edges and Dm^-1 rounded), the SVD's s2 by 64 eps |F|,
        // and det F moves by at most 3 (|F| + delta)^2 times either.
        let eps = Real::EPSILON as f64;
        let (mut largest_f, mut barrier_clear) = (0.0f64, true);
        if positions.len() == n {
            for corners in &tets {
                if let (Some(x0), Some(x)) = (
                    gather_wide(&rest, corners),
                    gather_wide(&positions, corners),
                ) {
                    let f = tet_gradient(&x0, &x);
                    let norm = f.iter().flatten().map(|e| e * e).sum::<f64>().sqrt();
                    let norm = if norm.is_nan() { f64::INFINITY } else { norm };
                    largest_f = largest_f.max(norm);
                    let (ds, dm_inv) = edge_and_inverse_norms(&x0, &x);
                    let delta = 8.0 * eps * ds * dm_inv;
                    let det_error = 3.0 * (norm + delta).powi(2) * (delta + 64.0 * eps * norm);
                    let j = dot(f[0], cross(f[1], f[2])).abs();
                    barrier_clear &= j >= 1e-2 && j >= 10.0 * det_error;
                }
            }
        }
        let (lambda, mu, physical) = draw_lame(draw);
        let threshold_physical = !draw.chance(16);
        let threshold = if threshold_physical {
            0.05 + draw_real::grid(draw, 1.0).abs() / 8.0 * 0.95
        } else {
            draw_real::wild(draw)
        };
        let moderate = physical && rest_physical && largest_f <= 1e3;
        let barrier_clear = moderate && largest_f <= 10.0 && barrier_clear;
        let finiteness = Finiteness {
            moderate,
            clamped: moderate && threshold_physical,
            within_limit: false,
            rest_physical,
        };
        if let Ok(m) = StVK::from_lame(lambda, mu) {
            let within_limit = Finiteness {
                within_limit: true,
                ..finiteness
            };
            tet_kernels(
                draw,
                &mesh,
                &rest,
                &m,
                "StVK",
                &positions,
                threshold,
                within_limit,
            );
        }
        if let Ok(m) = NeoHookean::from_lame(lambda, mu) {
            let barrier = Finiteness {
                moderate: barrier_clear,
                ..finiteness
            };
            tet_kernels(
                draw,
                &mesh,
                &rest,
                &m,
                "NeoHookean",
                &positions,
                threshold,
                barrier,
            );
        }
        if let Ok(m) = StableNeoHookean::from_lame(lambda, mu) {
            let within_limit = Finiteness {
                within_limit: true,
                ..finiteness
            };
            tet_kernels(
                draw,
                &mesh,
                &rest,
                &m,
                "StableNeoHookean",
                &positions,
                threshold,
                within_limit,
            );
        }
    }
}

/// What the deformation check of the kernels (`MeshError::DeformationRange`: an entry of an
/// element's `F` beyond `Material::deformation_limit`) may report, from an f64 computation of
/// every element's `F`: the elements it may name (up to and including the first one clearly
/// beyond the limit; elements within this precision's error in `F` of the limit may go either
/// way), and whether it must report one.
struct ElementScan {
    may_name: Vec<usize>,
    must_fail: bool,
    error: fn(usize) -> MeshError,
}

impl ElementScan {
    fn new<M: Material>(
        material: &M,
        rest: &[Vec3],
        tets: &[[u32; 4]],
        positions: &[Vec3],
    ) -> Self {
        let limit = material.deformation_limit() as f64;
        let eps = Real::EPSILON as f64;
        let mut scan = ElementScan {
            may_name: Vec::new(),
            must_fail: false,
            error: |element| MeshError::DeformationRange { element },
        };
        if limit == f64::INFINITY || positions.len() != rest.len() {
            return scan;
        }
        for (element, corners) in tets.iter().enumerate() {
            let (Some(x0), Some(x)) = (gather_wide(rest, corners), gather_wide(positions, corners))
            else {
                continue;
            };
            let f = tet_gradient(&x0, &x);
            // A NaN entry (overflowed terms of opposite signs, from wild positions) stands for
            // an entry beyond any limit: `max` would drop it.
            let largest = f.iter().flatten().fold(0.0f64, |m, e| {
                if e.is_nan() {
                    f64::INFINITY
                } else {
                    m.max(e.abs())
                }
            });
            let (ds, dm_inv) = edge_and_inverse_norms(&x0, &x);
            // F as this precision forms it is off by about 8 eps |Ds| |Dm^-1| per entry.
            let slack = 8.0 * eps * ds * dm_inv + 4.0 * eps * largest;
            let slack = if slack.is_nan() { f64::INFINITY } else { slack };
            // The kernels compare max(1, largest entry) with the limit.
            let largest = largest.max(1.0);
            if largest - slack > limit || !largest.is_finite() {
                scan.may_name.push(element);
                scan.must_fail = true;
                break;
            } else if largest + slack >= limit {
                scan.may_name.push(element);
            }
        }
        scan
    }

    /// What the mass check of `lumped_masses` (`MeshError::MassRange`) may report: the first
    /// element whose mass share `density / N * measure` is not a normal number at most
    /// `Real::MAX / element count`, from an f64 computation (shares within a relative `1e-6`
    /// of either end may go either way).
    fn masses(density: Real, corners: usize, measures: &[Real]) -> Self {
        let mut scan = ElementScan {
            may_name: Vec::new(),
            must_fail: false,
            error: |element| MeshError::MassRange { element },
        };
        let (low, high) = (
            Real::MIN_POSITIVE as f64,
            Real::MAX as f64 / measures.len().max(1) as f64,
        );
        for (element, &measure) in measures.iter().enumerate() {
            let share = density as f64 / corners as f64 * measure as f64;
            if share < low * (1.0 - 1e-6) || share > high * (1.0 + 1e-6) {
                scan.may_name.push(element);
                scan.must_fail = true;
                break;
            } else if share < low * (1.0 + 1e-6) || share > high * (1.0 - 1e-6) {
                scan.may_name.push(element);
            }
        }
        scan
    }
}

/// One check of a kernel: an outcome an independent scan knows (`None`: passes), or the
/// deformation check.
#[derive(Clone, Copy)]
enum Check {
    Known(Option<MeshError>),
    Deformation,
}

/// The results a kernel may return when it runs `checks` in order; `swappable_tail` also
/// allows the last two in the other order (the kernels differ in whether the output length or
/// the deformation is checked first, and the documentation does not order them).
fn acceptable(
    checks: &[Check],
    swappable_tail: bool,
    scan: &ElementScan,
) -> Vec<Result<(), MeshError>> {
    let run = |checks: &[Check]| {
        let mut results = Vec::new();
        for check in checks {
            match *check {
                Check::Known(Some(error)) => {
                    results.push(Err(error));
                    return results;
                }
                Check::Known(None) => {}
                Check::Deformation => {
                    results.extend(
                        scan.may_name
                            .iter()
                            .map(|&element| Err((scan.error)(element))),
                    );
                    if scan.must_fail {
                        return results;
                    }
                }
            }
        }
        results.push(Ok(()));
        results
    };
    let mut results = run(checks);
    if swappable_tail && checks.len() >= 2 {
        let mut swapped = checks.to_vec();
        let n = swapped.len();
        swapped.swap(n - 1, n - 2);
        results.extend(run(&swapped));
    }
    results
}

/// Checks a kernel's `result` against the `acceptable` ones and its output (`before`, `after`):
/// unchanged on error, finite on success when `finite_expected`.
#[allow(clippy::too_many_arguments)]
fn check_with<T: PartialEq + core::fmt::Debug>(
    kernel: &str,
    model: &str,
    result: Result<(), MeshError>,
    acceptable: &[Result<(), MeshError>],
    before: &T,
    after: &T,
    all_finite: bool,
    finite_expected: bool,
) {
    crate::trace(|| {
        let outcome = match (&result, finite_expected) {
            (Err(_), _) => "error",
            (Ok(()), true) => "ok, finiteness asserted",
            (Ok(()), false) => "ok, outside the documented range",
        };
        format!("{NAME} {kernel} {model}: {outcome}")
    });
    assert!(
        acceptable.contains(&result),
        "{NAME}: {kernel} ({model}) returned {result:?}; the documented checks allow {acceptable:?}"
    );
    match result {
        Err(_) => assert_eq!(
            before, after,
            "{NAME}: {kernel} ({model}) changed its output on error"
        ),
        Ok(()) => assert!(
            all_finite || !finite_expected,
            "{NAME}: {kernel} ({model}) gave a non-finite output in the documented range"
        ),
    }
}

/// When a tetrahedral kernel's success promises finite output.
#[derive(Clone, Copy)]
struct Finiteness {
    /// Physical moduli, body and `|F| <= 1e3` (neo-Hookean: clear of `J = 0`): every output.
    moderate: bool,
    /// The same for the clamped path (a threshold in `[0.05, 1]`; any model).
    clamped: bool,
    /// A model documented finite for every `F` within its deformation limit (StVK, stable
    /// neo-Hookean): its per-element stresses whenever the kernel accepts the input, and its
    /// per-element energies for a body of physical size (not their total, which can overflow).
    within_limit: bool,
    rest_physical: bool,
}

/// Every tetrahedral kernel with `material` at `positions`.
#[allow(clippy::too_many_arguments)]
fn tet_kernels<M: Material>(
    draw: &mut Draw<'_>,
    mesh: &TetMesh<'_>,
    rest: &[Vec3],
    material: &M,
    model: &str,
    positions: &[Vec3],
    threshold: Real,
    finiteness: Finiteness,
) {
    let n = mesh.vertex_count();
    let scan = ElementScan::new(material, rest, mesh.tets(), positions);
    let positions_check = Check::Known(expected_positions_error(n, positions));
    let threshold_check =
        Check::Known((!(threshold > 0.0 && threshold <= 1.0)).then_some(MeshError::ClampThreshold));
    for kernel in [
        "add_elastic_forces",
        "add_elastic_forces_principal",
        "add_elastic_forces_clamped",
    ] {
        let mut forces = draw_vectors::<Vec3>(draw, n);
        let before = bits_of(&forces);
        let forces_check = Check::Known(expected_output_error(Buffer::Forces, n, forces.len()));
        let (result, checks, finite) = match kernel {
            "add_elastic_forces" => (
                mesh.add_elastic_forces(material, positions, &mut forces),
                vec![positions_check, forces_check, Check::Deformation],
                finiteness.moderate,
            ),
            "add_elastic_forces_principal" => (
                mesh.add_elastic_forces_principal(material, positions, &mut forces),
                vec![positions_check, forces_check, Check::Deformation],
                finiteness.moderate,
            ),
            _ => (
                mesh.add_elastic_forces_clamped(material, threshold, positions, &mut forces),
                vec![
                    threshold_check,
                    positions_check,
                    forces_check,
                    Check::Deformation,
                ],
                finiteness.clamped,
            ),
        };
        let all_finite = forces.iter().all(|f| f.is_finite());
        check_with(
            kernel,
            model,
            result,
            &acceptable(&checks, true, &scan),
            &before,
            &bits_of(&forces),
            all_finite,
            finite,
        );
    }

    let energy = mesh.elastic_energy(material, positions);
    let energy_finite = energy.as_ref().map_or(true, |e| e.is_finite());
    check_with(
        "elastic_energy",
        model,
        energy.map(|_| ()),
        &acceptable(&[positions_check, Check::Deformation], false, &scan),
        &(),
        &(),
        energy_finite,
        // Within a model's deformation limit each element's energy is finite (below
        // `Real::MAX / 2^24` times its volume), but their sum over a body need not be: the
        // documented promise for the total is the moderate range only.
        finiteness.moderate,
    );

    let mut energies = draw_reals(draw, mesh.element_count());
    let before = real_bits(&energies);
    let result = mesh.element_energies(material, positions, &mut energies);
    let energies_check = Check::Known(expected_output_error(
        Buffer::Energies,
        mesh.element_count(),
        energies.len(),
    ));
    let all_finite = energies.iter().all(|e| e.is_finite());
    check_with(
        "element_energies",
        model,
        result,
        &acceptable(
            &[positions_check, energies_check, Check::Deformation],
            true,
            &scan,
        ),
        &before,
        &real_bits(&energies),
        all_finite,
        // Within a model's deformation limit each element's energy is finite on a body of
        // physical size.
        finiteness.moderate || (finiteness.within_limit && finiteness.rest_physical),
    );
    if let (Ok(total), Ok(())) = (energy, result) {
        // "summed element by element in order".
        let sum: Real = energies.iter().sum();
        assert!(
            total.to_bits() == sum.to_bits() || (total.is_nan() && sum.is_nan()),
            "{NAME}: TetMesh::elastic_energy ({model}) = {total} is not the in-order sum {sum} of element_energies"
        );
    }

    let mut stresses: Vec<Mat3> = (0..length_near(draw, mesh.element_count()))
        .map(|_| Mat3::from_diagonal(Vec3::splat(draw_real::grid(draw, 1.0))))
        .collect();
    let before: Vec<[u64; 9]> = stresses.iter().map(mat_bits).collect();
    let result = mesh.element_stresses(material, positions, &mut stresses);
    let stresses_check = Check::Known(expected_output_error(
        Buffer::Stresses,
        mesh.element_count(),
        stresses.len(),
    ));
    let all_finite = stresses.iter().all(|s| s.is_finite());
    let after: Vec<[u64; 9]> = stresses.iter().map(mat_bits).collect();
    check_with(
        "element_stresses",
        model,
        result,
        &acceptable(
            &[positions_check, stresses_check, Check::Deformation],
            true,
            &scan,
        ),
        &before,
        &after,
        all_finite,
        finiteness.moderate || finiteness.within_limit,
    );
}

fn mat_bits(m: &Mat3) -> [u64; 9] {
    m.to_cols_array().map(|x| x.to_bits().into())
}

/// The kernels the two triangle mesh types share, over position type `P`.
#[allow(clippy::too_many_arguments)]
fn triangle_kernels<P: Point>(
    draw: &mut Draw<'_>,
    mesh_name: &str,
    rest: &[P],
    tris: &[[u32; 3]],
    add_forces: &dyn Fn(&TriangleStVK, &[P], &mut [P]) -> Result<(), MeshError>,
    energy: &dyn Fn(&TriangleStVK, &[P]) -> Result<Real, MeshError>,
) {
    let n = rest.len();
    for _ in 0..=draw.up_to(1) {
        let positions = draw_positions(draw, rest);
        let mut largest_f: f64 = 0.0;
        if positions.len() == n {
            for corners in tris {
                if let (Some(x0), Some(x)) =
                    (gather_wide(rest, corners), gather_wide(&positions, corners))
                {
                    let norm = triangle_gradient_norm(&x0, &x);
                    largest_f = largest_f.max(if norm.is_nan() { f64::INFINITY } else { norm });
                }
            }
        }
        let (lambda, mu, physical) = draw_lame(draw);
        let Ok(stvk) = StVK::from_lame(lambda, mu) else {
            continue;
        };
        let material = TriangleStVK::new(&stvk);
        let finite_expected = physical && physical_size(rest) && largest_f <= 1e3;
        let positions_error = expected_positions_error(n, &positions);

        let mut forces = draw_vectors::<P>(draw, n);
        let before = bits_of(&forces);
        let result = add_forces(&material, &positions, &mut forces);
        let expected = positions_error.or(expected_output_error(Buffer::Forces, n, forces.len()));
        let all_finite = forces.iter().all(|f| f.finite());
        check_kernel(
            (mesh_name, "add_elastic_forces"),
            result,
            expected,
            &before,
            &bits_of(&forces),
            all_finite,
            finite_expected,
        );

        match (energy(&material, &positions), positions_error) {
            (result, Some(error)) => {
                assert_eq!(result, Err(error), "{NAME}: {mesh_name}::elastic_energy")
            }
            (Ok(e), None) => assert!(
                e.is_finite() || !finite_expected,
                "{NAME}: {mesh_name}::elastic_energy is {e} in the documented range"
            ),
            (Err(error), None) => {
                panic!("{NAME}: {mesh_name}::elastic_energy refused valid input: {error:?}")
            }
        }
    }
}

fn tri_mesh(draw: &mut Draw<'_>) {
    let (rest, tris) = draw_mesh::<Vec2, 3>(draw, tri_area);
    let rest_len = length_near(draw, tris.len());
    let mut rest_data = vec![TriRest::default(); rest_len];
    let outcome = TriMesh::new(&rest, &tris, &mut rest_data).map(|_| ());
    if !check_construction(
        &rest,
        &tris,
        rest_len,
        outcome,
        &rest_data,
        TriRest::new,
        tri_area,
        2,
    ) {
        return;
    }
    let Ok(mesh) = TriMesh::new(&rest, &tris, &mut rest_data) else {
        panic!("{NAME}: a second construction of the same mesh failed");
    };
    let areas: Vec<Real> = mesh.rest().iter().map(|r| r.area).collect();
    check_masses(
        "TriMesh::lumped_masses",
        draw,
        rest.len(),
        3,
        &areas,
        physical_size(&rest),
        |density, masses| mesh.lumped_masses(density, masses),
    );
    triangle_kernels(
        draw,
        "TriMesh",
        &rest,
        &tris,
        &|m, x, f| mesh.add_elastic_forces(m, x, f),
        &|m, x| mesh.elastic_energy(m, x),
    );
}

fn membrane_mesh(draw: &mut Draw<'_>) {
    let (rest, tris) = draw_mesh::<Vec3, 3>(draw, membrane_area);
    let rest_len = length_near(draw, tris.len());
    let mut rest_data = vec![TriRest::default(); rest_len];
    let outcome = MembraneMesh::new(&rest, &tris, &mut rest_data).map(|_| ());
    if !check_construction(
        &rest,
        &tris,
        rest_len,
        outcome,
        &rest_data,
        TriRest::membrane,
        membrane_area,
        2,
    ) {
        return;
    }
    let Ok(mesh) = MembraneMesh::new(&rest, &tris, &mut rest_data) else {
        panic!("{NAME}: a second construction of the same mesh failed");
    };
    let areas: Vec<Real> = mesh.rest().iter().map(|r| r.area).collect();
    check_masses(
        "MembraneMesh::lumped_masses",
        draw,
        rest.len(),
        3,
        &areas,
        physical_size(&rest),
        |density, masses| mesh.lumped_masses(density, masses),
    );
    triangle_kernels(
        draw,
        "MembraneMesh",
        &rest,
        &tris,
        &|m, x, f| mesh.add_elastic_forces(m, x, f),
        &|m, x| mesh.elastic_energy(m, x),
    );
}
