//! Conforming to a surface: a mesh already on it stays, an offset one is
//! pulled onto it, and a re-meshed input's cut creases do not pull the mesh
//! into them (distances to the input measured with the surface index).

use super::*;
use crate::model::Rigid;

fn random_rigid(k: u32) -> Rigid {
    let a = k as Real;
    Rigid {
        rotation: *Rotation3::new(Vector3::new(0.3 * a.sin(), 0.7 * a.cos(), 0.2 + 0.1 * a))
            .matrix(),
        translation: Vector3::new(a, -0.5 * a, 0.25),
    }
}

/// The sphere the conform tests fit to, and a rigid motion of it.
fn conform_sphere() -> (TriangleMesh, Rigid) {
    (
        crate::fixtures::sphere(Point3::origin(), 1.0, 32, 16),
        random_rigid(3),
    )
}

fn moved(points: &[Point3], m: &Rigid) -> Vec<Point3> {
    points.iter().map(|p| m.apply(p)).collect()
}

fn mean_distance(a: &[Point3], b: &[Point3]) -> Real {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).sum::<Real>() / a.len() as Real
}

/// An open pentagonal tube (radius 1, height 2) with `per_side` columns of
/// vertices on each side and their first column `offset` columns from the
/// side's start: offset 0 puts vertices on the five creases; 0.5 puts none
/// there, so the triangles between the last column of one side and the first
/// of the next cut across the crease, as a re-meshed capture's do.
fn pentagonal_tube(per_side: u32, rows: u32, offset: Real) -> TriangleMesh {
    let corner = |k: u32| {
        let a = std::f64::consts::TAU * k as Real / 5.0;
        Vector3::new(a.cos(), a.sin(), 0.0)
    };
    let columns = 5 * per_side;
    let mut mesh = TriangleMesh::default();
    for j in 0..=rows {
        for i in 0..columns {
            let u = (i as Real + offset) / per_side as Real;
            let (k, f) = (u.floor() as u32, u.fract());
            let p = corner(k) * (1.0 - f)
                + corner(k + 1) * f
                + Vector3::z() * (2.0 * j as Real / rows as Real - 1.0);
            mesh.positions.push(Point3::from(p));
        }
    }
    for j in 0..rows {
        for i in 0..columns {
            let at = |j: u32, i: u32| j * columns + i % columns;
            mesh.triangles
                .push([at(j, i), at(j, i + 1), at(j + 1, i + 1)]);
            mesh.triangles
                .push([at(j, i), at(j + 1, i + 1), at(j + 1, i)]);
        }
    }
    mesh
}

#[test]
fn conforming_keeps_a_mesh_already_on_the_surface_and_pulls_an_offset_one_onto_it() {
    let (base, m) = conform_sphere();
    let input = TriangleMesh {
        positions: moved(&base.positions, &m),
        ..base.clone()
    };
    let params = ConformParams::default();
    // Already right: every term of the energy is zero, so nothing moves.
    let kept = conform_frame(
        &base,
        &input.positions,
        &input,
        &base.bounding_box(),
        &params,
    )
    .unwrap();
    assert!(mean_distance(&kept, &input.positions) < 1e-9);
    // 2 % too large: lands on the surface, back where it belongs.
    let centre = m.apply(&Point3::origin());
    let offset: Vec<Point3> = input
        .positions
        .iter()
        .map(|p| centre + (p - centre) * 1.02)
        .collect();
    let fitted = conform_frame(&base, &offset, &input, &base.bounding_box(), &params).unwrap();
    let surface = SurfaceIndex::new(&input.positions, &input.triangles);
    let off_surface = fitted
        .iter()
        .map(|p| surface.distance(p))
        .fold(0.0, Real::max);
    let (before, after) = (
        mean_distance(&offset, &input.positions),
        mean_distance(&fitted, &input.positions),
    );
    assert!(
        off_surface < 1e-3 && after < 0.05 * before,
        "{off_surface} off the surface; {before} -> {after} from the truth"
    );
}

#[test]
fn conforming_to_a_remeshed_input_does_not_follow_its_cut_creases() {
    // The mesh has vertices on the creases; the input is the same tube
    // re-meshed with none there, its triangles cutting each crease by a
    // chamfer. Both moved by the same rigid motion: the mesh is already right.
    let base = pentagonal_tube(12, 8, 0.0);
    let m = random_rigid(5);
    let input = pentagonal_tube(12, 8, 0.5);
    let mut input = TriangleMesh {
        positions: moved(&input.positions, &m),
        ..input
    };
    let blended = moved(&base.positions, &m);
    // A stray point in the file, in no triangle, is not surface: it pulls
    // nothing.
    input
        .positions
        .push(blended[0] + (blended[0] - m.apply(&Point3::origin())) * 0.01);
    // The chamfer lies this far inside the creases (half a column on either
    // side, 36° off each side).
    let side = 2.0 * (36.0 as Real).to_radians().sin();
    let depth = 0.5 * side / 12.0 * (36.0 as Real).to_radians().sin();
    let surface = SurfaceIndex::new(&input.positions, &input.triangles);
    let cut = blended
        .iter()
        .map(|p| surface.distance(p))
        .fold(0.0, Real::max);
    assert!(
        (cut - depth).abs() < 0.05 * depth,
        "the input cuts the creases by {cut}, expected {depth}"
    );
    // Fitted to the input's vertices, which all lie on the tube's sides, the
    // mesh stays; fitted to its triangles it would sink into every chamfer.
    let fitted = conform_frame(
        &base,
        &blended,
        &input,
        &base.bounding_box(),
        &ConformParams::default(),
    )
    .unwrap();
    let moved_most = fitted
        .iter()
        .zip(&blended)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    assert!(
        moved_most < 0.05 * depth,
        "a vertex moved {moved_most}, against a chamfer {depth} deep"
    );
}
