//! Issue #24's isotropic remeshing on real scans at an edge length of 1 % of the diagonal:
//! at least 99 % of triangles with a smallest angle of 30° or more, mean distance to the
//! input no larger than MeshLab's (0.020 % of the diagonal, measured in the issue; with the
//! least-squares fit, the default, 10 % or more below keeping every vertex on the input), no new
//! non-manifold edges, no cracks, texture coordinates in their charts, seam vertices on
//! input seams, and, on the textured scans, texture colour deviation within 1 level RMS of
//! the decimation to the same face count; no face turned against the input except where the
//! input folds over itself; no triangle under 10° away from borders and seams. With
//! `adaptive = true` (1 % of the diagonal the longest edge, default tolerance and shortest
//! edge) on james and the bunny: the same checks, and closer to the input than the uniform
//! remesh at the same longest edge.

mod common;

use scanmill::mesh::Mesh;
use scanmill::mesh::build::LoadOptions;
use scanmill::mesh::topology::Topology;
use scanmill::metrics::surface::SurfaceIndex;
use scanmill::metrics::texture::TextureDeviation;
use scanmill::metrics::{MetricsOptions, compare};
use scanmill::ops::decimate::audit::{Audit, audit};
use scanmill::ops::decimate::{DecimateParams, decimate};
use scanmill::ops::remesh::quality::min_angle;
use scanmill::ops::remesh::{RemeshParams, remesh};

/// Scan `rel` numbered as `scanmill process` numbers it before a remesh
/// (`Mesh::reorder_for_locality`): what the step remeshes in a job.
fn scan(rel: &str) -> Mesh {
    scan_with(rel, &LoadOptions::default())
}

/// [`scan`], loaded with `options`.
fn scan_with(rel: &str, options: &LoadOptions) -> Mesh {
    let mut mesh = common::scan_with(rel, options);
    mesh.reorder_for_locality();
    mesh
}

fn params() -> RemeshParams {
    RemeshParams {
        edge_fraction: Some(0.01),
        ..RemeshParams::default()
    }
}

fn check(rel: &str, mesh: &Mesh) -> Mesh {
    check_with(rel, mesh, &params()).0
}

/// The checks above, with `params`; returns the result and its mean and largest distance to
/// the input.
fn check_with(rel: &str, mesh: &Mesh, params: &RemeshParams) -> (Mesh, f64, f64) {
    let (out, report) = remesh(mesh, params).unwrap();
    out.check_invariants().unwrap();
    let q = report.quality_after;
    assert!(q.share_min_angle_30 >= 0.99, "{rel}: {q:?}");
    let a = audit(mesh, &out);
    assert!(
        a.after.non_manifold_edges <= a.before.non_manifold_edges,
        "{rel}: {a:?}"
    );
    assert_eq!(a.chart_jumps, 0, "{rel}: chart jumps {a:?}");
    assert_eq!(a.seam_vertices_off_seam, 0, "{rel}: seam vertices {a:?}");
    assert_eq!(a.zero_area_faces, 0, "{rel}: zero-area {a:?}");
    let m = compare(&out, mesh, &MetricsOptions::default()).unwrap();
    assert!(
        m.distance.mean_relative <= 0.000_20,
        "{rel}: {:?}",
        m.distance
    );
    assert_eq!(m.topology.cracks, 0, "{rel}");
    turned_only_at_folds(rel, mesh, &out, report.edge_length);
    let slivers = slivers_inside(&out);
    assert!(slivers.is_empty(), "{rel}: slivers {slivers:?}");
    let (mean, max) = (m.distance.mean_relative, m.distance.max_relative);
    (out, mean, max)
}

/// Every output face turned against the input triangle closest to its centroid lies where
/// the input folds over itself: at least a fifth of the input triangles within two edge
/// lengths `l` of it face against that triangle (the remesh's repair pass leaves only these;
/// docs/remeshing.md); and there are at most 1 in 4,000 (without the repair pass james has
/// 19 of 17,228 and facefuns 9 of 16,424).
fn turned_only_at_folds(rel: &str, input: &Mesh, out: &Mesh, l: f64) {
    let index = SurfaceIndex::new(input, "input").unwrap();
    let turned = common::faces_against(input, out);
    for &t in &turned {
        let c = common::centroid(out, t);
        let reference = input.triangle_cross(index.closest(c).on.triangle as usize);
        let near: Vec<usize> = (0..input.triangles.len())
            .filter(|&u| common::centroid(input, u).distance(c) < 2.0 * l)
            .collect();
        let against = near
            .iter()
            .filter(|&&u| input.triangle_cross(u).dot(reference) < 0.0)
            .count();
        assert!(
            5 * against >= near.len(),
            "{rel}: face {t} at {c} turned where the input does not fold ({against} of {} against)",
            near.len()
        );
    }
    assert!(
        4000 * turned.len() <= out.triangles.len(),
        "{rel}: {} faces turned of {}",
        turned.len(),
        out.triangles.len()
    );
}

/// The faces with a smallest angle under 10° none of whose corners is on a border, a seam
/// or a non-manifold edge or vertex (issue #24: "no angle below 10° except where a border
/// or seam forces it"), with their smallest angle.
fn slivers_inside(out: &Mesh) -> Vec<(usize, f64)> {
    let topo = Topology::new(out);
    let mut on_line: Vec<bool> = (0..out.positions.len() as u32)
        .map(|v| topo.is_non_manifold_vertex(v))
        .collect();
    for e in 0..topo.edge_count() as u32 {
        if topo.is_boundary_edge(e) || topo.is_seam_edge(e) || topo.is_non_manifold_edge(e) {
            for v in topo.edge_vertices(e) {
                on_line[v as usize] = true;
            }
        }
    }
    (0..out.triangles.len())
        .filter(|&t| {
            let corners = topo.triangle_vertices(t as u32);
            !corners.iter().any(|&v| on_line[v as usize])
        })
        .map(|t| (t, min_angle(out.triangle_positions(t))))
        .filter(|&(_, angle)| angle < 10.0)
        .collect()
}

/// James at 1 % with 3 iterations left one such face (6.9°, near (21, −124, −82)) where the
/// input folds: its short edge could neither collapse (the link condition one way, the
/// length bound the other) nor flip, and its ends could not relax, without laying a face
/// across the fold; the sliver pass moves one end along the fold
/// (`ops::remesh::slivers`). The checks above hold too.
#[test]
fn james_three_iterations_has_no_sliver_inside() {
    let rel = "textured/james_face_stereo_capture/james.obj";
    let params = RemeshParams {
        iterations: 3,
        ..params()
    };
    check_with(rel, &scan(rel), &params);
}

/// The adaptive remesh passes the same checks, has more triangles than the uniform one at
/// its longest edge, and is closer to the input, on average and at worst.
fn adaptive_closer(rel: &str, mesh: &Mesh) {
    let adaptive = RemeshParams {
        adaptive: true,
        ..params()
    };
    let (a, a_mean, a_max) = check_with(rel, mesh, &adaptive);
    let (u, u_mean, u_max) = check_with(rel, mesh, &params());
    assert!(a.triangles.len() > u.triangles.len(), "{rel}");
    assert!(a_mean < u_mean, "{rel}: mean {a_mean} vs uniform {u_mean}");
    assert!(a_max < u_max, "{rel}: max {a_max} vs uniform {u_max}");
}

#[test]
fn james_adaptive() {
    let rel = "textured/james_face_stereo_capture/james.obj";
    // Its shortest edges sit on its folded borders, where an input triangle hangs off the
    // scan by one vertex: no face there may lose its area (isotropic::undo_degenerate).
    adaptive_closer(rel, &scan(rel));
}

#[test]
fn bunny_adaptive() {
    let rel = "untextured/stanford_bunny/bun_zipper.ply";
    adaptive_closer(rel, &scan(rel));
}

/// Texture deviation RMS of `out` against `mesh` (its input).
fn texture_rms(rel: &str, mesh: &Mesh, out: &Mesh) -> f64 {
    match compare(out, mesh, &MetricsOptions::default())
        .unwrap()
        .texture
    {
        TextureDeviation::Measured { rms, .. } => rms,
        other => panic!("{rel}: texture deviation not measured: {other:?}"),
    }
}

/// Texture deviation RMS of the remesh within 1 level of the decimation to its face count;
/// returns the remesh's and the decimation's.
fn texture_like_decimation(rel: &str, mesh: &Mesh, out: &Mesh) -> (f64, f64) {
    let dec = DecimateParams {
        target_faces: Some(out.triangles.len()),
        ..DecimateParams::default()
    };
    let (d, _) = decimate(mesh, &dec).unwrap();
    let (r, d) = (texture_rms(rel, mesh, out), texture_rms(rel, mesh, &d));
    assert!(r <= d + 1.0, "{rel}: remesh {r} vs decimation {d}");
    (r, d)
}

/// With `bake_texture`, James remeshed at 2 % of the diagonal (fewer triangles than the
/// input, so that the decimation to the same count is a real one) shows the photo as the
/// decimation does or better (docs/remeshing.md: 1.56 against 1.96 levels RMS; without the
/// bake 4.04), and much better than the same remesh without the bake.
#[test]
fn james_baked_texture_like_decimation() {
    let rel = "textured/james_face_stereo_capture/james.obj";
    let mesh = scan(rel);
    let at = |bake_texture| RemeshParams {
        edge_fraction: Some(0.02),
        bake_texture,
        ..RemeshParams::default()
    };
    let (plain, _) = remesh(&mesh, &at(false)).unwrap();
    let (baked, report) = remesh(&mesh, &at(true)).unwrap();
    baked.check_invariants().unwrap();
    assert!(baked.triangles.len() < mesh.triangles.len());
    assert_eq!(
        baked.triangles, plain.triangles,
        "the bake changes only the image"
    );
    assert_eq!(
        report.bake.as_ref().map(|b| b.images),
        Some(1),
        "{report:?}"
    );
    let (r, d) = texture_like_decimation(rel, &mesh, &baked);
    assert!(r <= d, "{rel}: baked {r} vs decimation {d}");
    let unbaked = texture_rms(rel, &mesh, &plain);
    assert!(
        r <= 0.6 * unbaked,
        "{rel}: baked {r} vs not baked {unbaked}"
    );
}

/// The least-squares fit (the default) leaves the result closer to the input than keeping
/// every vertex on it (`on_surface = true`): 22–34 % closer on facefuns, james, the bunny
/// and igea (docs/remeshing.md); at least 10 % here. Both pass all the checks above.
fn fit_closer(rel: &str, mesh: &Mesh) {
    let (_, fit_mean, _) = check_with(rel, mesh, &params());
    let on_surface = RemeshParams {
        on_surface: true,
        ..params()
    };
    let (_, on_mean, _) = check_with(rel, mesh, &on_surface);
    assert!(
        fit_mean <= 0.9 * on_mean,
        "{rel}: mean distance {fit_mean} fitted, {on_mean} on the surface"
    );
}

#[test]
fn james() {
    let rel = "textured/james_face_stereo_capture/james.obj";
    fit_closer(rel, &scan(rel));
}

/// James's ragged border is followed, not cut across: with the default refined border
/// (edges of L/2 along it) the result is closer to the input than with edges of L there,
/// on average and at worst (docs/remeshing.md: mean 0.0145 → 0.0128 %, largest 0.96 →
/// 0.51 % of the diagonal), and passes the same checks.
#[test]
fn james_border_followed() {
    let rel = "textured/james_face_stereo_capture/james.obj";
    let mesh = scan(rel);
    let (_, mean, max) = check_with(rel, &mesh, &params());
    let coarse = RemeshParams {
        border_edge_ratio: Some(1.0),
        ..params()
    };
    let (_, coarse_mean, coarse_max) = check_with(rel, &mesh, &coarse);
    assert!(mean <= 0.95 * coarse_mean, "mean {mean} vs {coarse_mean}");
    assert!(max <= 0.75 * coarse_max, "max {max} vs {coarse_max}");
}

#[test]
fn bunny() {
    let rel = "untextured/stanford_bunny/bun_zipper.ply";
    fit_closer(rel, &scan(rel));
}

#[test]
#[ignore = "facefuns with its texture and a decimation for comparison: about a minute in a debug build; run with --release -- --ignored"]
fn facefuns_texture_like_decimation() {
    let rel = "textured/facefuns_di3d_face/example.obj";
    let options = LoadOptions {
        texture_override: Some(common::data("textured/facefuns_di3d_face/example.png")),
        ..LoadOptions::default()
    };
    let mesh = scan_with(rel, &options);
    let out = check(rel, &mesh);
    texture_like_decimation(rel, &mesh, &out);
}

#[test]
#[ignore = "igea has 269k triangles: slow in a debug build; run with --release -- --ignored"]
fn igea() {
    let rel = "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz";
    check(rel, &scan(rel));
}

/// The USNM coral (photogrammetry: 20,640 seam edges, crumpled, 31 non-manifold edges) at
/// 0.5 % of the diagonal. Its atlas keeps the share of good triangles below the bar above
/// (docs/remeshing.md, "Not done yet"), so this checks only what must hold on any input:
/// no zero-area face (the repair pass once traded two turned faces for two without area
/// here), no new non-manifold edge, no crack, no chart jump; and few seam vertices off the
/// input's seams (0 beside 29,556 seam edges; 64 before the faces on one side of a line
/// vertex agreed on its coordinate, export::agree_along_lines, 7 before line vertices moved
/// along their lines only, isotropic::relaxed_on_line).
#[test]
fn photogrammetry_atlas_without_zero_area_faces() {
    photogrammetry_atlas(
        "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
        0.005,
        1500,
    );
}

/// The coral adaptive at 1 %: the repair pass splits edges there, and the sliver pass after
/// it reads the sizes of the new vertices (it once read past the size field and panicked).
#[test]
fn photogrammetry_atlas_adaptive() {
    let rel = "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz";
    let mesh = scan(rel);
    let params = RemeshParams {
        adaptive: true,
        ..params()
    };
    let (out, report) = remesh(&mesh, &params).unwrap_or_else(|e| panic!("{rel}: {e}"));
    out.check_invariants().unwrap();
    assert!(
        report.counts.turned.splits > 0,
        "{:?}",
        report.counts.turned
    );
    let slivers = report.counts.slivers;
    assert!(slivers.left <= slivers.found, "{slivers:?}");
}

/// The esp32cam scan (Meshroom: a raw photogrammetry atlas, ragged borders) at 1 %: the
/// same checks. It had 16 seam vertices off the input's seams before line vertices moved
/// along their lines only.
#[test]
fn raw_photogrammetry_atlas_keeps_its_seams() {
    photogrammetry_atlas("textured/esp32cam_meshroom_raw/texturedMesh.obj", 0.01, 400);
}

fn photogrammetry_atlas(rel: &str, fraction: f64, one_turned_in: usize) {
    let (mesh, out, a) = remesh_at(rel, fraction);
    out.check_invariants().unwrap();
    assert_eq!(a.zero_area_faces, 0, "{a:?}");
    assert!(
        a.after.non_manifold_edges <= a.before.non_manifold_edges,
        "{a:?}"
    );
    assert_eq!(a.chart_jumps, 0, "{a:?}");
    assert!(a.seam_vertices_off_seam <= 2, "{a:?}");
    let m = compare(&out, &mesh, &MetricsOptions::default()).unwrap();
    assert_eq!(m.topology.cracks, 0);
    // The repair pass leaves faces turned where the input is crumpled; its flips, moves,
    // collapses and splits bring them down to this share (esp32cam 48 → 36 of 15,621 and
    // the coral 210 → 133 of 230,161 when the splits and the far moves came).
    let turned = common::faces_against(&mesh, &out).len();
    assert!(
        turned * one_turned_in <= out.triangles.len(),
        "{rel}: {turned} faces turned of {}",
        out.triangles.len()
    );
}

/// James at 0.5 % of the diagonal (72k faces): its seams stay where the input's are. Where
/// an input seam ends inside its chart, the faces between two lines at the seam's end once
/// read the end vertex's coordinate from different sides of the seam, one seam vertex off
/// the input's seams (export::corner_vertex_uvs); and a seam vertex that relax had moved
/// along its chord stayed 0.88 mm off the seam where the projection back was refused
/// (isotropic::relaxed_on_line).
#[test]
fn james_fine_keeps_its_seams() {
    let (_, _, a) = remesh_at("textured/james_face_stereo_capture/james.obj", 0.005);
    assert_eq!(a.seam_vertices_off_seam, 0, "{a:?}");
    assert_eq!(a.zero_area_faces, 0, "{a:?}");
    assert_eq!(a.chart_jumps, 0, "{a:?}");
}

/// Scan `rel` remeshed (the defaults) at `fraction` of its diagonal: the input, the result
/// and the audit of the two.
fn remesh_at(rel: &str, fraction: f64) -> (Mesh, Mesh, Audit) {
    let mesh = scan(rel);
    let params = RemeshParams {
        edge_fraction: Some(fraction),
        ..RemeshParams::default()
    };
    let (out, _) = remesh(&mesh, &params).unwrap();
    let a = audit(&mesh, &out);
    (mesh, out, a)
}
