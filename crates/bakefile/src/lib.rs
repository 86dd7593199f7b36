//! The binary file format of PRT bakes (`.prtb`), format version 1.2 (SPEC.md).
//!
//! A bake file holds, per object of a scene, blocks of spherical-harmonic transfer
//! coefficients (unshadowed, shadowed, visibility, interreflected), plus the environment
//! lighting, BRDF projections and everything needed to interpret them: the SH convention,
//! colour space, seed, tool, settings and the baker's decisions; and what an engine needs to
//! bind the numbers to its own data: each object's mesh (positions, normals, triangles, whose
//! hash is the object's geometry hash) and, for per-pixel bakes, the camera and each object's
//! coverage of every pixel. `SPEC.md` beside this crate describes every byte so that an engine
//! can read bakes without this code; `tools/prtb_reader.py` is a reader written from it alone.
//!
//! - [`encode`] / [`write_bake`] (atomic) write a [`Bake`] with f32 or f16 coefficients.
//! - [`decode`] / [`read_bake`] validate everything and return an owned [`Bake`];
//!   [`read_bake`] ([`decode_owned`]) hands the file's buffer over to a reflectance field, whose
//!   values stay in the file's precision ([`FieldValues`]).
//! - [`BakeView`] validates once and then lends coefficient arrays in place (zero-copy).
//! - [`merge`] joins shards of a sharded bake into the bytes an unsharded bake would have;
//!   [`split`] is its inverse.
//! - [`summary`] / [`BakeView::summary`] describe a bake for `prt inspect`.
//! - [`geometry_hash`] ties a bake to its mesh.
//!
//! ```
//! use prt_bakefile::*;
//!
//! let bake = Bake {
//!     objects: vec![ObjectBake {
//!         name: "floor".into(),
//!         geometry_hash: geometry_hash(&[[0.0, 0.0, 0.0]], &[]),
//!         point_count: 2,
//!         point_first: 0,
//!         points_in_file: 2,
//!         order: 2,
//!         channels: 1,
//!         blocks: vec![TransferBlock {
//!             kind: TransferKind::ShadowedDiffuse,
//!             data: vec![0.5; 2 * 4],
//!             cpca: None,
//!         }],
//!         ..ObjectBake::default()
//!     }],
//!     ..Bake::default()
//! };
//! let bytes = encode(&bake, ScalarType::F16)?;
//! let view = BakeView::new(&bytes)?;
//! assert_eq!(view.objects()[0].order, 2);
//! assert_eq!(decode(&bytes)?, bake);
//! # Ok::<(), BakeFileError>(())
//! ```

mod atlas_uv;
mod encode;
mod error;
mod field;
mod hash;
mod io;
mod layout;
mod located;
mod material;
mod merge;
mod meta;
mod model;
mod read_bytes;
mod read_geometry;
mod read_header;
mod read_meta;
mod read_objects;
mod read_pass;
mod read_scene;
mod scalar;
mod summary;
mod view;

pub use atlas_uv::{atlas_corner_uvs, atlas_integers, ATLAS_UV_QUANTUM};
pub use encode::encode;
pub use error::BakeFileError;
pub use field::FieldValues;
pub use hash::{geometry_hash, uv_hash};
pub use io::{read_bake, write_bake};
pub use layout::{
    Tag, HEADER_SIZE, MAGIC, MUST_UNDERSTAND_FLAGS, PAYLOAD_ALIGNMENT, SECTION_ENTRY_SIZE,
    SECTION_FLAG_REQUIRED, VERSION_MAJOR, VERSION_MINOR,
};
pub use located::{BlockInfo, ObjectInfo, SectionEntry};
pub use material::{
    material_line, CookTorranceParams, LambertParams, LobeParams, MaterialBinding, MaterialModel,
    MaterialSource, MirrorParams, PbrParams, RoughParams, Variation,
};
pub use merge::{merge, split};
pub use meta::ShConvention;
pub use model::{
    Bake, BakeMeta, BrdfLobe, BrdfProjection, CameraInfo, Coverage, Cpca, Decision,
    EnvCoefficients, EnvPrecision, GlossyBrdfTable, MeshGeometry, ObjectBake, PassHit, PassInfo,
    PassState, RayStats, ReflectanceField, SampleKind, ScalarType, ShardInfo, ToolInfo,
    TransferBlock, TransferKind,
};
pub use summary::{
    camera_line, summary, BlockSummary, CoverageSummary, FileSummary, MeshSummary, ObjectSummary,
    SectionSummary, Summary,
};
pub use view::{decode, decode_owned, BakeView, Coefficients};
