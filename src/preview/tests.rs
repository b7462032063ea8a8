use super::*;
use crate::mesh::Material;
use crate::mesh::Texture;
use crate::mesh::shapes::{grid, uv_sphere};

fn options(size: u32, supersample: u32) -> PreviewOptions {
    PreviewOptions {
        size,
        supersample,
        ..PreviewOptions::default()
    }
}

#[test]
fn labels_are_tidy() {
    assert_eq!(nice_ceil(0.0), (0.0, "0".into()));
    assert_eq!(nice_ceil(0.043).1, "0.05");
    assert_eq!(nice_ceil(0.021).1, "0.025");
    assert_eq!(nice_ceil(0.02).1, "0.02");
    assert_eq!(nice_ceil(1.0).1, "1");
    assert_eq!(nice_ceil(7.0).1, "10");
    assert_eq!(nice_ceil(130.0).1, "200");
    assert_eq!(nice_ceil(0.0011).1, "0.002");
    assert!((nice_ceil(0.021).0 - 0.025).abs() < 1e-15);
    assert_eq!(significant(0.01234), "0.012");
    assert_eq!(significant(3.456), "3.5");
    assert_eq!(significant(25.0), "25");
}

#[test]
fn options_validate() {
    assert!(PreviewOptions::default().validate().is_ok());
    assert!(options(16, 1).validate().is_err());
    assert!(options(256, 9).validate().is_err());
    let o = PreviewOptions {
        view: Axis::PosY,
        up: Some(Axis::NegY),
        ..PreviewOptions::default()
    };
    assert!(o.validate().unwrap_err().contains("parallel"));
}

/// The column range of panel `i` and the rows of the mesh viewport.
fn mesh_rows(size: u32) -> std::ops::Range<u32> {
    let l = Layout::new(size);
    l.title_band..size - l.legend_band
}

#[test]
fn a_quad_fills_the_fitted_frame() {
    // A 1 × 1 quad seen from the front, fitted with 3 % margins in a 256-wide viewport:
    // it covers a square of 0.94 × 256 pixels (or the viewport's height, if smaller).
    let quad = grid(1, 1);
    let p = render(&quad, &quad, &options(256, 1)).unwrap();
    let (w, h) = p.image.dimensions();
    assert_eq!((w, h), (768, 256));
    let rows = mesh_rows(256);
    let side = 0.94 * (rows.end - rows.start).min(256) as f64;
    let covered = (0..256)
        .flat_map(|x| rows.clone().map(move |y| (x, y)))
        .filter(|&(x, y)| p.image.get_pixel(x, y).0 != BACKGROUND)
        .count() as f64;
    assert!(
        (covered - side * side).abs() <= 4.0 * side,
        "{covered} vs {}",
        side * side
    );
    // Lit head-on and untextured: neutral grey, the same in the result panel.
    let mid_y = (rows.start + rows.end) / 2;
    assert_eq!(p.image.get_pixel(128, mid_y).0, [190, 190, 190]);
    assert_eq!(p.image.get_pixel(256 + 128, mid_y).0, [190, 190, 190]);
    assert_eq!(p.figures.max_percent, 0.0);
}

#[test]
fn a_textured_quad_shows_its_texture_right_way_up() {
    // Texture: top half red, bottom half blue. OBJ texture coordinates have v up, so the
    // quad's top (y = 1, v = 1) must be red and its bottom blue.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.png");
    let mut tex = RgbImage::new(8, 8);
    for (_, y, p) in tex.enumerate_pixels_mut() {
        *p = if y < 4 {
            Rgb([255, 0, 0])
        } else {
            Rgb([0, 0, 255])
        };
    }
    tex.save(&path).unwrap();
    let mut quad = grid(1, 1);
    quad.materials = vec![Material {
        name: "m".into(),
        diffuse_texture: Some(Texture {
            name: "t.png".into(),
            path: path.clone(),
            size: Some((8, 8)),
            embedded: None,
        }),
        ..Material::default()
    }];
    quad.triangle_materials = vec![0; quad.triangles.len()];
    let p = render(&quad, &quad, &options(256, 2)).unwrap();
    let rows = mesh_rows(256);
    let (top, bottom) = (rows.start + 30, rows.end - 30);
    assert_eq!(p.image.get_pixel(128, top).0, [255, 0, 0]);
    assert_eq!(p.image.get_pixel(128, bottom).0, [0, 0, 255]);
    assert_eq!(p.image.get_pixel(256 + 128, top).0, [255, 0, 0]);
}

#[test]
fn distance_panel_of_vertices_on_the_input_does_not_scale_to_rounding() {
    // A remesh puts its vertices on the input to rounding; the bar must not colour that.
    let m = uv_sphere(1.0, 24, 32);
    let mut r = m.clone();
    for p in &mut r.positions {
        *p *= 1.0 + 1e-15;
    }
    let p = render(&m, &r, &options(256, 1)).unwrap();
    assert!(p.figures.max_percent > 0.0 && p.figures.max_percent < 1e-10);
    assert_eq!(p.figures.scale_percent, 0.001);
}

#[test]
fn distance_panel_of_a_mesh_against_itself_is_all_zero_colour() {
    let m = uv_sphere(1.0, 24, 32);
    let p = render(&m, &m, &options(256, 1)).unwrap();
    // The bar keeps a readable top (MIN_SCALE_PERCENT) and every vertex is at its bottom.
    assert_eq!(
        (p.figures.max_percent, p.figures.scale_percent),
        (0.0, 0.001)
    );
    let zero = ramp::viridis(0.0);
    let rows = mesh_rows(256);
    let mut drawn = 0;
    for y in rows {
        for x in 512..768 {
            let c = p.image.get_pixel(x, y).0;
            if c == BACKGROUND {
                continue;
            }
            drawn += 1;
            // The zero colour times some light: the same hue (a multiple of the colour),
            // allowing for rounding and the anti-aliased silhouette.
            let light = c[2] as f64 / zero[2];
            for k in 0..3 {
                assert!(
                    (c[k] as f64 - zero[k] * light).abs() <= 2.0 || light > 1.2,
                    "{x} {y} {c:?}"
                );
            }
        }
    }
    assert!(drawn > 10_000, "{drawn}");
}

#[test]
fn distance_colours_grow_with_distance() {
    let reference = grid(8, 8);
    let mut bent = reference.clone();
    for p in &mut bent.positions {
        p.z = 0.05 * p.x; // farther from the reference towards +x
    }
    let p = render(&reference, &bent, &options(256, 1)).unwrap();
    assert!(p.figures.max_percent > 0.0);
    let rows = mesh_rows(256);
    let y = (rows.start + rows.end) / 2;
    let sum = |x| {
        p.image
            .get_pixel(x, y)
            .0
            .iter()
            .map(|&c| c as u32)
            .sum::<u32>()
    };
    // Viridis gets lighter along the ramp: the right side (far) is lighter than the left.
    assert!(sum(512 + 220) > sum(512 + 36) + 100);
}

#[test]
fn nearer_surface_hides_the_farther() {
    // Two parallel quads, the nearer one (larger z, seen looking along −z) red.
    let mut far = grid(1, 1);
    for p in &mut far.positions {
        p.z = -1.0;
    }
    let mut near = grid(1, 1);
    near.colors = vec![[255, 0, 0, 255]; 4];
    far.colors = vec![[0, 255, 0, 255]; 4];
    let mut both = far.clone();
    let offset = both.positions.len() as u32;
    both.positions.extend(&near.positions);
    both.colors.extend(&near.colors);
    both.wedges
        .extend(near.wedges.iter().map(|w| crate::mesh::Wedge {
            vertex: w.vertex + offset,
            texcoord: None,
            normal: None,
        }));
    both.triangles
        .extend(near.triangles.iter().map(|t| t.map(|w| w + offset)));
    let p = render(&both, &both, &options(128, 1)).unwrap();
    let rows = mesh_rows(128);
    let c = p.image.get_pixel(64, (rows.start + rows.end) / 2).0;
    assert!(c[0] > 200 && c[1] == 0, "{c:?}");
}

#[test]
fn empty_meshes_are_errors_not_panics() {
    let m = grid(1, 1);
    assert!(render(&Mesh::default(), &m, &PreviewOptions::default()).is_err());
    assert!(render(&m, &Mesh::default(), &PreviewOptions::default()).is_err());
}

#[test]
fn overlapping_layers_beyond_the_overdraw_budget_are_not_drawn() {
    let sphere = uv_sphere(1.0, 16, 32);
    let mut stack = sphere.clone();
    for _ in 0..150 {
        stack.triangles.extend_from_slice(&sphere.triangles);
    }
    assert!(render(&sphere, &sphere, &options(128, 1)).is_ok());
    match render(&sphere, &stack, &options(128, 1)) {
        Err(PreviewError::Overdraw { panel, depth }) => {
            assert_eq!(panel, "result");
            assert!(depth > MAX_OVERDRAW, "{depth}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_budget_counts_clipped_bounding_boxes() {
    // A right triangle over 10 × 10 pixel centres, half of it outside a 5-wide image.
    let vertices = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
    let within = |t: [u32; 3], width, budget| {
        raster::rasterise_within(&vertices, &[t], width, 20, budget).map(|g| g.fragments)
    };
    assert_eq!(
        within([0, 1, 2], 5, 49),
        Err(raster::OverBudget { tests: 50 })
    );
    assert!(within([0, 1, 2], 5, 50).is_ok());
    assert_eq!(
        within([0, 1, 2], 20, 99),
        Err(raster::OverBudget { tests: 100 })
    );
    // Out-of-range corners cost nothing, and draw nothing.
    assert_eq!(within([0, 1, 7], 20, 0), Ok(0));
}
