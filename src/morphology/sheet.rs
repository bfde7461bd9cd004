//! Direct tension estimate on a **2.5-D cell sheet**: cells given as open patches of one surface (an
//! epidermis segmented on its outer wall, as MorphoGraphX or cellcomplex/TissueLab export it), where
//! each triangle belongs to one cell and neighbouring cells share the mesh's vertices along their
//! walls. With no cell volumes there is no 3-D force balance; the walls are lines on the surface, and
//! at every vertex where three or more walls meet (a tricellular junction) their line tensions balance
//! in the surface's tangent plane, Σ_k T_k t_k = 0 (CellFIT-2D, Brodland et al. 2014, on a curved
//! surface).
//!
//! **Walls.** A mesh edge whose two faces belong to different cells is a wall edge; the wall between
//! cells a and b is the chain of its edges from one junction (a vertex on three or more wall edges) to
//! the next, through vertices on exactly two. An edge with one face lies on the sheet's rim (its
//! cut): walls that reach the rim give no equation there, since the force across the cut is unknown.
//!
//! **Tangents.** At a junction x₀ with surface normal n (the principal direction of its faces'
//! area-weighted normals, so the faces' winding does not matter) each wall piece's vertices are
//! projected onto the tangent plane; a line (principal direction of the points) and, from four
//! vertices on, a circle (algebraic least squares) are fitted to all of them, and the circle is kept
//! where it fits clearly better ([`CIRCLE_OVER_LINE_RSS`]): exact on straight walls and circular arcs,
//! and one noisy vertex moves the tangent less than a chord's. The wall's unit tangent at x₀ is the
//! fitted curve's, pointing into the wall. Two equations per junction, in two directions of the
//! tangent plane, weighted by 1/√Σ_k (L̄/L_k)² (L_k the arms' lengths, L̄ their mean): a wall's
//! direction is known to about (vertex error)/L_k, so junctions at very short walls count less.
//!
//! **Solve.** The same mean-constrained least squares as the 3-D estimate (see
//! [`super::tensions`]): tensions are relative, scaled so that the gauge holds (by default the mean of
//! all wall tensions is 1, or a named wall's is); unknowns sharing no junction form separate groups;
//! a wall with no junction (both ends on the rim) is undetermined. Standard deviations propagate an
//! isotropic noise of the vertex coordinates to first order (each tangent's derivatives with respect
//! to its wall's vertices, by central differences), its variance estimated from the junctions'
//! residuals; a wall's vertices enter both of its junctions, so their errors are correlated, which a
//! clustering by junction would miss.
//!
//! **Pressures.** Where walls are curved, 2-D Young–Laplace p_a − p_b = T_ab κ_ab (κ the wall's
//! geodesic curvature, positive when it bulges into b) gives each cell's in-plane pressure relative to
//! the mean of the cells the curved walls link it to (tension per length; 0 for straight walls).
//!
//! Deterministic: every loop runs in a fixed order.

use super::tensions::{Gauge, Row, TensionError, laplace_least_squares_rows, median, solve_tensions};
use crate::geometry::{Real, Vec3};
use crate::mesh::Tissue;
use nalgebra::Matrix3;
use std::collections::{BTreeMap, BTreeSet};

/// A wall whose projected vertices lie on their fitted line to within this fraction of its length
/// (root of the summed squared distances) is straight: no circle is tried, its curvature is 0.
pub const STRAIGHT_WALL: Real = 1e-6;

/// One wall's estimate (a pair of cells; several wall pieces between the same two cells share it).
#[derive(Clone, Debug, PartialEq)]
pub struct WallTension {
    /// Cell labels, `cell_a < cell_b`.
    pub cell_a: u32,
    pub cell_b: u32,
    /// Line tension in units of the gauge; `None` when undetermined.
    pub tension: Option<Real>,
    pub tension_sd: Option<Real>,
    pub determined: bool,
    /// Length along the surface (m), all pieces together.
    pub length: Real,
    /// Junctions with an equation that involve this wall.
    pub junctions: usize,
    /// Geodesic curvature (1/m) of the wall's fitted circle (0 where a line fits as well), positive when
    /// it bulges into `cell_b`; `None` for a wall with fewer than [`MIN_CURVATURE_POINTS`] vertices.
    pub curvature: Option<Real>,
    /// The wall reaches the sheet's rim at one end at least.
    pub on_rim: bool,
}

/// One cell of the sheet.
#[derive(Clone, Debug, PartialEq)]
pub struct SheetCell {
    pub cell: u32,
    /// Area of its patch (m²).
    pub area: Real,
    /// Walls with other cells.
    pub walls: usize,
    /// The patch reaches the sheet's rim (the cell is cut).
    pub on_rim: bool,
    /// In-plane pressure relative to the mean of the cells that determined curved walls link it to
    /// (gauge tension per metre), with its sd; `None` when no determined wall links it.
    pub pressure_relative: Option<Real>,
    pub pressure_relative_sd: Option<Real>,
}

/// The whole sheet estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct SheetTensionMap {
    /// Ascending by (cell_a, cell_b).
    pub walls: Vec<WallTension>,
    /// Ascending by label.
    pub cells: Vec<SheetCell>,
    /// For every face of the tissue (cell after cell, in tissue order), the wall (index in `walls`)
    /// that one of its edges lies on; `None` for a face inside its cell.
    pub face_wall: Vec<Option<usize>>,
    /// The wall pieces as vertex polylines (global positions, m), with the index of their wall in `walls`.
    pub pieces: Vec<(usize, Vec<Vec3>)>,
    /// What fixes the scale.
    pub gauge: String,
    /// Junctions with an equation, and junctions on the rim left out.
    pub junctions: usize,
    pub junctions_on_rim: usize,
    /// Edges shared by more than two faces (left out with their vertices).
    pub non_manifold_edges: usize,
    pub condition_number: Option<Real>,
    pub spectral_gap: Option<Real>,
    /// Rms and median over junctions of |Σ T_k t_k| (units of the gauge).
    pub residual_rms: Option<Real>,
    pub residual_median: Option<Real>,
    pub warnings: Vec<String>,
}

/// The sheet's mesh: one vertex per distinct position, every face with its cell.
struct Sheet {
    points: Vec<Vec3>,
    faces: Vec<([usize; 3], u32)>,
}

impl Sheet {
    fn of(tissue: &Tissue) -> Self {
        let mut index: BTreeMap<[u64; 3], usize> = BTreeMap::new();
        let mut points = Vec::new();
        let mut faces = Vec::new();
        for cell in tissue.cells() {
            let mesh = cell.mesh();
            let global: Vec<usize> = mesh
                .positions()
                .iter()
                .map(|p| {
                    let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
                    *index.entry(key).or_insert_with(|| {
                        points.push(*p);
                        points.len() - 1
                    })
                })
                .collect();
            for t in mesh.triangles() {
                faces.push(([global[t[0] as usize], global[t[1] as usize], global[t[2] as usize]], cell.id().0));
            }
        }
        Self { points, faces }
    }
}

/// Whether `tissue` is a 2.5-D cell sheet: at least two cells, every cell an open patch (its mesh has
/// an edge with one face), no triangle in two cells (a 3-D multi-material mesh shares its interfaces),
/// and some vertex shared by two cells.
pub fn is_sheet(tissue: &Tissue) -> bool {
    if tissue.cells().len() < 2 {
        return false;
    }
    let open = tissue.cells().iter().all(|c| {
        let mut edges: BTreeMap<(u32, u32), usize> = BTreeMap::new();
        for t in c.mesh().triangles() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        edges.values().any(|&n| n == 1)
    });
    if !open {
        return false;
    }
    let sheet = Sheet::of(tissue);
    // A multi-material mesh whose every cell has a hole would pass the tests above, but its cells
    // share their interface triangles; a sheet's cells never do.
    let mut triangles: BTreeSet<[usize; 3]> = BTreeSet::new();
    for (f, _) in &sheet.faces {
        let mut key = *f;
        key.sort_unstable();
        if !triangles.insert(key) {
            return false;
        }
    }
    let mut owner: Vec<Option<u32>> = vec![None; sheet.points.len()];
    sheet.faces.iter().any(|(f, c)| {
        f.iter().any(|&v| match owner[v] {
            Some(o) => o != *c,
            None => {
                owner[v] = Some(*c);
                false
            }
        })
    })
}

/// Fewest vertices of a wall piece for a curvature (a circle needs three, and one more to tell it
/// from a line): walls of one to three edges have none, and give no pressure.
pub const MIN_CURVATURE_POINTS: usize = 4;

/// A wall's vertices fit a circle instead of a line only when the circle's residual is below this
/// fraction of the line's (a noisy straight wall stays straight; an exact arc has none).
pub const CIRCLE_OVER_LINE_RSS: Real = 0.25;

/// The unit tangent at `p[0]` of the wall through the points `p` (projected on the plane normal to
/// `n`), pointing into the wall, and its signed curvature about `n` (positive when it turns
/// counter-clockwise about `n`). A line (principal direction) is fitted to all the points, and a
/// circle (algebraic fit, then the tangent where the circle passes nearest `p[0]`) to four or more;
/// the circle is kept when it fits clearly better ([`CIRCLE_OVER_LINE_RSS`]). Both use every point,
/// so one noisy vertex moves the tangent less than a chord's.
fn tangent(p: &[Vec3], n: &Vec3) -> Option<(Vec3, Real)> {
    let project = |x: &Vec3| {
        let d = x - p[0];
        d - n * n.dot(&d)
    };
    let chord = project(p.last()?);
    let length = chord.norm();
    if length == 0.0 || !length.is_finite() {
        return None;
    }
    let e1 = chord / length;
    let e2 = n.cross(&e1);
    let local: Vec<(Real, Real)> = p.iter().map(project).map(|d| (d.dot(&e1), d.dot(&e2))).collect();
    let m = local.len() as Real;
    let (mx, my) = (local.iter().map(|q| q.0).sum::<Real>() / m, local.iter().map(|q| q.1).sum::<Real>() / m);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for &(x, y) in &local {
        sxx += (x - mx) * (x - mx);
        sxy += (x - mx) * (y - my);
        syy += (y - my) * (y - my);
    }
    // The principal direction of the points' scatter and its residual (the smaller eigenvalue).
    let half = 0.5 * (sxx - syy);
    let root = (half * half + sxy * sxy).sqrt();
    let rss_line = (0.5 * (sxx + syy) - root).max(0.0);
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let mut line = e1 * angle.cos() + e2 * angle.sin();
    if line.dot(&e1) < 0.0 {
        line = -line;
    }
    if local.len() < MIN_CURVATURE_POINTS || rss_line <= (STRAIGHT_WALL * length).powi(2) {
        return Some((line, 0.0));
    }
    // x² + y² + D x + E y + F = 0 by least squares (Kåsa), centred on the mean for conditioning.
    let mut a = nalgebra::Matrix3::<Real>::zeros();
    let mut b = nalgebra::Vector3::<Real>::zeros();
    for &(x, y) in &local {
        let (u, v) = (x - mx, y - my);
        let row = nalgebra::Vector3::new(u, v, 1.0);
        a += row * row.transpose();
        b -= row * (u * u + v * v);
    }
    let Some(sol) = a.lu().solve(&b) else { return Some((line, 0.0)) };
    let centre = (mx - 0.5 * sol[0], my - 0.5 * sol[1]);
    let r2 = 0.25 * (sol[0] * sol[0] + sol[1] * sol[1]) - sol[2];
    if !(r2 > 0.0 && r2.is_finite()) {
        return Some((line, 0.0));
    }
    let radius = r2.sqrt();
    let rss_circle: Real = local.iter().map(|&(x, y)| ((x - centre.0).hypot(y - centre.1) - radius).powi(2)).sum();
    if rss_circle >= CIRCLE_OVER_LINE_RSS * rss_line {
        return Some((line, 0.0));
    }
    // Tangent at the circle's point nearest p[0] (the origin): perpendicular to the centre's direction.
    let to_centre = e1 * centre.0 + e2 * centre.1;
    let mut t = n.cross(&to_centre);
    if t.dot(&e1) < 0.0 {
        t = -t;
    }
    let t = t.normalize();
    // The centre on the left of the direction of travel (n × t) turns counter-clockwise about n.
    let sign = if n.cross(&t).dot(&to_centre) > 0.0 { 1.0 } else { -1.0 };
    Some((t, sign / radius))
}

/// ∂t/∂x for the tangent of [`tangent`] at `p[0]` with respect to every coordinate of every vertex
/// of the arm (`chain` its vertex ids), by central differences of step `h`: (3·vertex + axis, ∂t).
fn tangent_derivatives(chain: &[usize], p: &[Vec3], n: &Vec3, h: Real) -> Vec<(usize, Vec3)> {
    let mut out = Vec::with_capacity(3 * p.len());
    let mut moved = p.to_vec();
    for (k, &vertex) in chain.iter().enumerate() {
        for axis in 0..3 {
            let original = moved[k][axis];
            moved[k][axis] = original + h;
            let plus = tangent(&moved, n);
            moved[k][axis] = original - h;
            let minus = tangent(&moved, n);
            moved[k][axis] = original;
            if let (Some((a, _)), Some((b, _))) = (plus, minus) {
                out.push((3 * vertex + axis, (a - b) / (2.0 * h)));
            }
        }
    }
    out
}

/// The principal direction of the area-weighted normals of `faces` at a vertex.
fn vertex_normal(points: &[Vec3], faces: &[[usize; 3]]) -> Option<Vec3> {
    let mut m = Matrix3::<Real>::zeros();
    for f in faces {
        let c = (points[f[1]] - points[f[0]]).cross(&(points[f[2]] - points[f[0]]));
        let area2 = c.norm();
        if area2 > 0.0 {
            let u = c / area2;
            m += u * u.transpose() * area2;
        }
    }
    let eig = m.symmetric_eigen();
    let (k, _) = eig.eigenvalues.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    let n: Vec3 = eig.eigenvectors.column(k).into_owned();
    n.iter().all(|x| x.is_finite()).then_some(n)
}

/// Estimates every wall's line tension at the junctions of a 2.5-D sheet (see the module docs).
/// `gauge`: [`Gauge::MediumMean`] means the mean of all wall tensions (a sheet has no medium).
pub fn estimate_sheet_tensions(tissue: &Tissue, gauge: Gauge, value: Real) -> Result<SheetTensionMap, TensionError> {
    if tissue.cells().len() < 2 {
        return Err(TensionError::TooFewCells { cells: tissue.cells().len() });
    }
    if !(value.is_finite() && value > 0.0) {
        return Err(TensionError::InvalidGaugeValue { value });
    }
    if let Some(c) =
        tissue.cells().iter().find(|c| c.mesh().positions().iter().any(|p| !p.iter().all(|v| v.is_finite())))
    {
        return Err(TensionError::NonFinite { cell: c.id().0 });
    }
    let sheet = Sheet::of(tissue);
    let points = &sheet.points;
    let mut warnings = Vec::new();
    // Edges → their faces.
    let mut edge_faces: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
    let mut vertex_faces: Vec<Vec<usize>> = vec![Vec::new(); points.len()];
    for (i, (f, _)) in sheet.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            edge_faces.entry((a.min(b), a.max(b))).or_default().push(i);
            vertex_faces[f[k]].push(i);
        }
    }
    let mut rim = vec![false; points.len()];
    let mut non_manifold = 0usize;
    // Wall edges: (a, b) → the pair of cells.
    let mut wall_edges: BTreeMap<(usize, usize), (u32, u32)> = BTreeMap::new();
    for (&(a, b), fs) in &edge_faces {
        match fs.as_slice() {
            [_] => {
                rim[a] = true;
                rim[b] = true;
            }
            [f, g] => {
                let (ca, cb) = (sheet.faces[*f].1, sheet.faces[*g].1);
                if ca != cb {
                    wall_edges.insert((a, b), (ca.min(cb), ca.max(cb)));
                }
            }
            _ => {
                non_manifold += 1;
                rim[a] = true;
                rim[b] = true;
            }
        }
    }
    if non_manifold > 0 {
        warnings.push(format!(
            "{non_manifold} edges are shared by more than two faces; their vertices are treated as the rim (no equation)"
        ));
    }
    let mut wall_neighbours: Vec<Vec<usize>> = vec![Vec::new(); points.len()];
    for &(a, b) in wall_edges.keys() {
        wall_neighbours[a].push(b);
        wall_neighbours[b].push(a);
    }
    if wall_edges.is_empty() {
        return Err(TensionError::NoJunctions { delta: 0.0 });
    }
    let is_junction = |v: usize| wall_neighbours[v].len() >= 3;
    // Trace every wall piece from each of its ends (junction or rim vertex, or any vertex of a closed
    // loop), collecting the pieces once.
    let pair_index: BTreeMap<(u32, u32), usize> = {
        let pairs: BTreeSet<(u32, u32)> = wall_edges.values().copied().collect();
        pairs.into_iter().enumerate().map(|(i, p)| (p, i)).collect()
    };
    let pairs: Vec<(u32, u32)> = pair_index.keys().copied().collect();
    let mut visited: BTreeSet<(usize, usize)> = BTreeSet::new();
    let mut pieces: Vec<(usize, Vec<usize>)> = Vec::new();
    let trace = |start: usize, next: usize| {
        let mut chain = vec![start, next];
        while !is_junction(*chain.last().unwrap()) && !rim[*chain.last().unwrap()] {
            let v = *chain.last().unwrap();
            let prev = chain[chain.len() - 2];
            match wall_neighbours[v].iter().find(|&&w| w != prev) {
                Some(&w) if w != chain[0] => chain.push(w),
                Some(&w) => {
                    chain.push(w);
                    break;
                }
                None => break,
            }
        }
        chain
    };
    let ends: Vec<usize> =
        (0..points.len()).filter(|&v| !wall_neighbours[v].is_empty() && (is_junction(v) || rim[v])).collect();
    let loop_starts: Vec<usize> = (0..points.len()).filter(|&v| !wall_neighbours[v].is_empty()).collect();
    for &start in ends.iter().chain(loop_starts.iter()) {
        for &next in &wall_neighbours[start] {
            if visited.contains(&(start.min(next), start.max(next))) {
                continue;
            }
            let chain = trace(start, next);
            for w in chain.windows(2) {
                visited.insert((w[0].min(w[1]), w[0].max(w[1])));
            }
            let pair = wall_edges[&(start.min(next), start.max(next))];
            pieces.push((pair_index[&pair], chain));
        }
    }
    // Each junction's arms: the pieces that start or end there.
    let mut arms: BTreeMap<usize, Vec<(usize, Vec<usize>)>> = BTreeMap::new();
    for (wall, chain) in &pieces {
        for reversed in [false, true] {
            let mut c = chain.clone();
            if reversed {
                c.reverse();
            }
            if is_junction(c[0]) && !rim[c[0]] && !(reversed && chain.first() == chain.last()) {
                arms.entry(c[0]).or_default().push((*wall, c));
            }
        }
    }
    let junctions_on_rim = (0..points.len()).filter(|&v| is_junction(v) && rim[v]).count();
    let mut rows: Vec<Row> = Vec::new();
    // Each junction's (wall, unit tangent) arms, in the order of their equations.
    let mut junction_rows: Vec<Vec<(usize, Vec3)>> = Vec::new();
    let mut junctions_used = vec![0usize; pairs.len()];
    for (&j, list) in &arms {
        let faces: Vec<[usize; 3]> = vertex_faces[j].iter().map(|&f| sheet.faces[f].0).collect();
        let Some(n) = vertex_normal(points, &faces) else { continue };
        let positions: Vec<Vec<Vec3>> = list.iter().map(|(_, c)| c.iter().map(|&v| points[v]).collect()).collect();
        let Some(tangents) = list
            .iter()
            .zip(&positions)
            .map(|((wall, _), p)| tangent(p, &n).map(|(t, _)| (*wall, t)))
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        // A wall's direction is known to about (vertex noise)/(its length): a junction's equations
        // weigh 1/√Σ(L̄/L_k)², so junctions at short walls count less (scale-free: L̄ the mean arm).
        let lengths: Vec<Real> =
            positions.iter().map(|p| p.windows(2).map(|w| (w[1] - w[0]).norm()).sum::<Real>()).collect();
        let mean_length = lengths.iter().sum::<Real>() / lengths.len() as Real;
        let weight = 1.0 / lengths.iter().map(|l| (mean_length / l).powi(2)).sum::<Real>().sqrt();
        let e1 = {
            let t = tangents[0].1 - n * n.dot(&tangents[0].1);
            t.normalize()
        };
        if !e1.iter().all(|x| x.is_finite()) {
            continue;
        }
        let e2 = n.cross(&e1);
        let line = junction_rows.len();
        // How each tangent moves with its arm's vertices (central differences), for the sds.
        let moves: Vec<Vec<(usize, Vec3)>> = list
            .iter()
            .zip(&positions)
            .zip(&lengths)
            .map(|(((_, chain), p), length)| tangent_derivatives(chain, p, &n, 1e-8 * length))
            .collect();
        for e in [e1, e2] {
            let mut coefficients: BTreeMap<usize, Real> = BTreeMap::new();
            let mut noise = Vec::new();
            for ((wall, t), arm_moves) in tangents.iter().zip(&moves) {
                *coefficients.entry(*wall).or_default() += weight * t.dot(&e);
                noise.extend(arm_moves.iter().map(|(coordinate, dt)| (*wall, *coordinate, weight * dt.dot(&e))));
            }
            rows.push(Row { coefficients: coefficients.into_iter().collect(), line, sample: line, noise });
        }
        let mut seen: Vec<usize> = tangents.iter().map(|(w, _)| *w).collect();
        seen.sort_unstable();
        seen.dedup();
        for w in seen {
            junctions_used[w] += 1;
        }
        junction_rows.push(tangents);
    }
    if rows.is_empty() {
        return Err(TensionError::NoJunctions { delta: 0.0 });
    }
    let (gauge_unknowns, gauge_name): (Vec<usize>, String) = match gauge {
        Gauge::MediumMean => ((0..pairs.len()).collect(), "the mean wall tension".to_string()),
        Gauge::Interface(a, b) => {
            let key = (a.min(b), a.max(b));
            match pair_index.get(&key) {
                Some(&u) => (vec![u], format!("the tension of wall {}-{}", key.0, key.1)),
                None => {
                    return Err(TensionError::UnknownGaugeInterface {
                        a,
                        b,
                        labels: format!("{} walls, e.g. {}-{}", pairs.len(), pairs[0].0, pairs[0].1),
                    });
                }
            }
        }
    };
    let solved = solve_tensions(&rows, pairs.len(), &gauge_unknowns, &gauge_name, value)?;
    warnings.extend(solved.warnings);
    // Residuals per junction.
    let mut imbalance: Vec<Real> = junction_rows
        .iter()
        .filter_map(|tangents| {
            let mut f = Vec3::zeros();
            for (w, t) in tangents {
                f += t * solved.tension[*w]?;
            }
            Some(f.norm())
        })
        .collect();
    let residual_rms = (!imbalance.is_empty())
        .then(|| (imbalance.iter().map(|x| x * x).sum::<Real>() / imbalance.len() as Real).sqrt());
    let residual_median = median(&mut imbalance);
    // Walls: length, curvature (the longest piece's circle about its midpoint normal), rim.
    let mut walls: Vec<WallTension> = pairs
        .iter()
        .enumerate()
        .map(|(u, &(a, b))| WallTension {
            cell_a: a,
            cell_b: b,
            tension: solved.tension[u],
            tension_sd: solved.tension_sd[u],
            determined: solved.tension[u].is_some(),
            length: 0.0,
            junctions: junctions_used[u],
            curvature: None,
            on_rim: false,
        })
        .collect();
    let mut longest = vec![0.0; pairs.len()];
    for (wall, chain) in &pieces {
        let length: Real = chain.windows(2).map(|w| (points[w[1]] - points[w[0]]).norm()).sum();
        let w = &mut walls[*wall];
        w.length += length;
        w.on_rim |= rim[chain[0]] || rim[*chain.last().unwrap()];
        if length > longest[*wall] {
            longest[*wall] = length;
            w.curvature = wall_curvature(points, &vertex_faces, &sheet.faces, chain, (w.cell_a, w.cell_b));
        }
    }
    let (cells, pressure_warning) = sheet_cells(tissue, &sheet, &rim, &walls);
    warnings.extend(pressure_warning);
    let pieces = pieces.into_iter().map(|(w, c)| (w, c.iter().map(|&v| points[v]).collect())).collect();
    let face_wall = sheet
        .faces
        .iter()
        .map(|(f, _)| {
            (0..3).find_map(|k| {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                wall_edges.get(&(a.min(b), a.max(b))).map(|pair| pair_index[pair])
            })
        })
        .collect();
    Ok(SheetTensionMap {
        walls,
        cells,
        face_wall,
        pieces,
        gauge: gauge_name,
        junctions: junction_rows.len(),
        junctions_on_rim,
        non_manifold_edges: non_manifold,
        condition_number: solved.condition,
        spectral_gap: solved.gap,
        residual_rms,
        residual_median,
        warnings,
    })
}

/// The geodesic curvature of a wall piece: the circle through its first vertex fitted to the others in
/// the tangent plane at its middle vertex, signed positive when it bulges into `pair.1` (the centre on
/// `pair.0`'s side).
fn wall_curvature(
    points: &[Vec3],
    vertex_faces: &[Vec<usize>],
    faces: &[([usize; 3], u32)],
    chain: &[usize],
    pair: (u32, u32),
) -> Option<Real> {
    if chain.len() < MIN_CURVATURE_POINTS {
        return None;
    }
    let mid = chain[chain.len() / 2];
    let n = vertex_normal(points, &vertex_faces[mid].iter().map(|&f| faces[f].0).collect::<Vec<_>>())?;
    let p: Vec<Vec3> = chain.iter().map(|&v| points[v]).collect();
    let (t, kappa) = tangent(&p, &n)?;
    if kappa == 0.0 {
        return Some(0.0);
    }
    // The centre lies at p0 + (n × t)/κ (κ signed about n). Which cell is on that side: the face of the
    // first edge's neighbourhood whose centroid lies towards it.
    let towards = n.cross(&t) * kappa.signum();
    let (a, b) = (chain[0], chain[1]);
    let side = vertex_faces[a]
        .iter()
        .filter(|&&f| faces[f].0.contains(&b))
        .map(|&f| {
            let c = (points[faces[f].0[0]] + points[faces[f].0[1]] + points[faces[f].0[2]]) / 3.0;
            ((c - points[a]).dot(&towards), faces[f].1)
        })
        .max_by(|x, y| x.0.total_cmp(&y.0))?;
    let magnitude = kappa.abs();
    Some(if side.1 == pair.0 { magnitude } else { -magnitude })
}

/// Every cell's area, walls, rim flag and relative in-plane pressure from the determined walls' 2-D
/// Young–Laplace (see the module docs).
fn sheet_cells(
    tissue: &Tissue,
    sheet: &Sheet,
    rim: &[bool],
    walls: &[WallTension],
) -> (Vec<SheetCell>, Option<String>) {
    let mut cells: BTreeMap<u32, SheetCell> = BTreeMap::new();
    for c in tissue.cells() {
        cells.insert(
            c.id().0,
            SheetCell {
                cell: c.id().0,
                area: c.mesh().face_areas().iter().sum(),
                walls: 0,
                on_rim: false,
                pressure_relative: None,
                pressure_relative_sd: None,
            },
        );
    }
    for (f, c) in &sheet.faces {
        if f.iter().any(|&v| rim[v])
            && let Some(cell) = cells.get_mut(c)
        {
            cell.on_rim = true;
        }
    }
    for w in walls {
        for c in [w.cell_a, w.cell_b] {
            if let Some(cell) = cells.get_mut(&c) {
                cell.walls += 1;
            }
        }
    }
    let ids: Vec<u32> = cells.keys().copied().collect();
    let index: BTreeMap<u32, usize> = ids.iter().enumerate().map(|(i, &c)| (c, i)).collect();
    let laplace: Vec<(usize, usize, Real, Real)> = walls
        .iter()
        .filter_map(|w| {
            let (t, sd, k) = (w.tension?, w.tension_sd?, w.curvature?);
            Some((index[&w.cell_a], index[&w.cell_b], t * k, (sd * k).powi(2)))
        })
        .collect();
    let mut warning = None;
    if !laplace.is_empty() {
        let linked: BTreeSet<usize> = laplace.iter().flat_map(|&(a, b, _, _)| [a, b]).collect();
        let unknowns: Vec<usize> = linked.into_iter().collect();
        match laplace_least_squares_rows(&laplace, &unknowns) {
            Some((p, cov, _)) => {
                for (l, &i) in unknowns.iter().enumerate() {
                    let cell = cells.get_mut(&ids[i]).expect("every index names a cell");
                    cell.pressure_relative = Some(p[l]);
                    cell.pressure_relative_sd = Some(cov[(l, l)].max(0.0).sqrt());
                }
            }
            None => {
                warning = Some("the in-plane pressures could not be solved (Young–Laplace least squares failed)".into())
            }
        }
    }
    (cells.into_values().collect(), warning)
}
