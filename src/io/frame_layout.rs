//! What a frame of mochi's holds and is named: the arrays of its `.vtu`, in the order they are
//! written (shared by a whole frame's `.vtu`, a piece's and the `.pvtu` that names pieces), and
//! the stem of a frame's file names.

/// The stem of the names of the frame of step `step` (`frame_{step:08}`).
pub(super) fn frame_stem(step: u64) -> String {
    format!("frame_{step:08}")
}

/// The arrays of a frame's `.vtu`, each an appended block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Block {
    Radius,
    Velocity,
    Speed,
    AngularVelocity,
    Id,
    Material,
    Contacts,
    Clump,
    Points,
    Connectivity,
    Offsets,
    Types,
}

/// The blocks of a frame with a history's `contacts` or not, with `clumps` or not, in the
/// order they are written.
pub(super) fn blocks_with(contacts: bool, clumps: bool) -> Vec<Block> {
    [
        Block::Radius,
        Block::Velocity,
        Block::Speed,
        Block::AngularVelocity,
        Block::Id,
        Block::Material,
        Block::Contacts,
        Block::Clump,
        Block::Points,
        Block::Connectivity,
        Block::Offsets,
        Block::Types,
    ]
    .into_iter()
    .filter(|&b| b != Block::Contacts || contacts)
    .filter(|&b| b != Block::Clump || clumps)
    .collect()
}

impl Block {
    /// `wide`: cell indices need 64 bits (more than `i32::MAX` spheres).
    pub(super) fn vtk_type(self, wide: bool) -> &'static str {
        match self {
            Block::Radius | Block::Velocity | Block::Speed | Block::AngularVelocity => "Float32",
            Block::Points => "Float64",
            Block::Id | Block::Contacts => "UInt32",
            Block::Connectivity | Block::Offsets if wide => "Int64",
            Block::Connectivity | Block::Offsets | Block::Clump => "Int32",
            Block::Material | Block::Types => "UInt8",
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Block::Radius => "radius",
            Block::Velocity => "velocity",
            Block::Speed => "speed",
            Block::AngularVelocity => "angular_velocity",
            Block::Id => "id",
            Block::Material => "material",
            Block::Contacts => "contacts",
            Block::Clump => "clump",
            Block::Points => "Points",
            Block::Connectivity => "connectivity",
            Block::Offsets => "offsets",
            Block::Types => "types",
        }
    }

    /// The element of the `<Piece>` that lists the array.
    pub(super) fn section(self) -> &'static str {
        match self {
            Block::Radius
            | Block::Velocity
            | Block::Speed
            | Block::AngularVelocity
            | Block::Id
            | Block::Material
            | Block::Contacts
            | Block::Clump => "PointData",
            Block::Points => "Points",
            Block::Connectivity | Block::Offsets | Block::Types => "Cells",
        }
    }

    pub(super) fn components(self) -> usize {
        match self {
            Block::Velocity | Block::AngularVelocity | Block::Points => 3,
            _ => 1,
        }
    }

    /// Bytes of one value, as [`Block::vtk_type`] says.
    pub(super) fn value_bytes(self, wide: bool) -> usize {
        match self {
            Block::Connectivity | Block::Offsets if wide => 8,
            Block::Points => 8,
            Block::Material | Block::Types => 1,
            _ => 4,
        }
    }

    /// Bytes of data (without the length header) for `n` spheres.
    pub(super) fn data_bytes(self, n: usize, wide: bool) -> u64 {
        (n * self.components() * self.value_bytes(wide)) as u64
    }
}
