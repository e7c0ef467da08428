//! The parts of an FMU's interface (see [`super::interface`], which reads them): its FMI
//! version, how values travel, an array's dimensions, its ports and parameters. Types only,
//! so that the readers of both FMI versions and the interface share them without a circle.

use modbot_grid::component::{ParamType, ParamValue, PortType};

use super::ranges::Range;

/// The most elements an FMU's array may have here (a port is one record on the grid).
pub const MAX_ELEMENTS: u64 = 1 << 16;

/// The FMI version of an FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Version {
    Fmi2,
    Fmi3,
}

impl Version {
    pub fn name(self) -> &'static str {
        match self {
            Version::Fmi2 => "2.0",
            Version::Fmi3 => "3.0",
        }
    }
}

/// How values travel to and from the FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// FMI 2 Real, FMI 3 Float64.
    Real,
    /// FMI 2 Integer, FMI 3 Int32.
    Int32,
    /// FMI 3 Int64.
    Int64,
    /// FMI 3 UInt64: structural parameters (array sizes).
    UInt64,
    /// FMI 2 and 3 Boolean.
    Bool,
}

/// One dimension of an FMI 3 array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extent {
    /// A fixed number of elements (`<Dimension start="n"/>`).
    Fixed(u64),
    /// The value of the structural parameter or constant with this value reference
    /// (`<Dimension valueReference="r"/>`).
    Of(u32),
}

/// An input or output.
#[derive(Debug, Clone, PartialEq)]
pub struct Port {
    pub name: String,
    pub ty: PortType,
    pub kind: Kind,
    /// Its value references: one per element (FMI 2), or one for an array variable (FMI 3).
    pub refs: Vec<u32>,
    /// An FMI 3 array's dimensions (empty for a scalar or an FMI 2 array, whose size is fixed).
    pub shape: Vec<Extent>,
}

/// A parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    pub name: String,
    pub ty: ParamType,
    pub kind: Kind,
    pub refs: Vec<u32>,
    /// Its start value (what the FMU has unless a description sets it).
    pub start: ParamValue,
    /// An FMI 3 array's dimensions, as for a [`Port`].
    pub shape: Vec<Extent>,
    /// The sizes of its dimensions at the start values, or as [`super::interface::Interface::sized`] made them.
    pub dims: Vec<u64>,
    /// Its declared range (`min`, `max`, or its declared type's): a value outside is refused.
    pub range: Range,
    /// Whether it is a structural parameter (FMI 3), set in Configuration Mode.
    pub structural: bool,
}

/// What a component needs to know of an FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct Interface {
    pub version: Version,
    pub model_name: String,
    /// The name of its binary (`binaries/<platform>/<model_identifier>.so`).
    pub model_identifier: String,
    /// FMI 2's guid, FMI 3's instantiation token.
    pub token: String,
    pub description: String,
    pub inputs: Vec<Port>,
    pub outputs: Vec<Port>,
    pub params: Vec<Param>,
    /// The UInt64 constants a `Dimension` may name: (value reference, value).
    pub constants: Vec<(u32, u64)>,
}
