//! Octree vertex clustering (spec/decimation.md §5.1–5.5): algorithm v (`cluster`) and
//! algorithm vo (`cluster-keep`).

use super::quadric::Weights;
use super::{DecimateParams, DecimateReport};
use crate::mesh::Mesh;

pub fn run<const M: usize>(
    mesh: &Mesh,
    _params: &DecimateParams,
    _w: Weights<M>,
) -> (Mesh, DecimateReport) {
    (mesh.clone(), DecimateReport::default())
}
