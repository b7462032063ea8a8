use super::corners::Corners;
use super::lines::Lines;
use super::*;
use crate::mesh::shapes;

fn working(mesh: &Mesh) -> (Corners, Lines) {
    let topo = Topology::new(mesh);
    let lines = Lines::new(mesh, &topo, None);
    (build::build(mesh, &topo, &lines), lines)
}

#[test]
fn splits_keep_the_table_whole() {
    let mesh = shapes::grid(4, 4);
    let (mut c, lines) = working(&mesh);
    c.check().unwrap();
    let l = mesh.mean_edge_length() / 5.0;
    let n = isotropic::split_long(&mut c, &lines, 4.0 / 3.0 * l);
    assert!(n > 0);
    c.check().unwrap();
}
