//! Typed `u32` indices, so a node index is never passed where a face index is expected.

use std::fmt;

macro_rules! index_type {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize)]
        #[serde(transparent)]
        pub struct $name(pub u32);

        impl $name {
            /// The index as `usize`, for slicing.
            #[inline]
            pub fn index(self) -> usize {
                self.0 as usize
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}", self.0)
            }
        }
    };
}

index_type!(
    /// Index of a node (vertex) within one cell's mesh.
    NodeId
);
index_type!(
    /// Index of a triangle within one cell's mesh.
    FaceId
);
index_type!(
    /// Stable identity of a cell in a tissue. Never reused after the cell dies; for cells read from a
    /// labelled image or mesh it is the input label.
    CellId
);
