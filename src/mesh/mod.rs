//! The mesh data model and its input/output. Depends on nothing else in the crate.

pub mod build;
pub mod compact;
pub mod error;
pub mod files;
pub mod gltf;
pub mod io;
pub mod limits;
pub mod model;
pub mod mtl;
pub mod obj;
pub mod ply;
pub mod reorder;
pub mod shapes;
pub mod stl;
pub mod summary;
pub mod texture;
pub mod topology;
pub mod wedges;

pub use build::{Corner, LoadOptions, LoadReport, MeshBuilder};
pub use error::{Location, MeshError};
pub use io::{SaveOptions, load, save, save_reserving};
pub use limits::InputLimits;
pub use model::{EmbeddedImage, Index, MapFile, Material, Mesh, Texture, Wedge};
pub use summary::MeshSummary;
pub use topology::{BoundaryChain, EdgeKind, OrderedRing, RingBuffers, Topology, TopologyCounts};
