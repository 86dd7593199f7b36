//! The scalar types a bake file stores its values in.

use serde::{Deserialize, Serialize};

/// How coefficients of transfer blocks are stored in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScalarType {
    /// IEEE 754 binary32, 4 bytes.
    F32,
    /// IEEE 754 binary16, 2 bytes; values beyond ±65504 are refused by the encoder.
    F16,
}

impl ScalarType {
    /// Size of one scalar in bytes.
    #[must_use]
    pub const fn size(self) -> usize {
        match self {
            ScalarType::F32 => 4,
            ScalarType::F16 => 2,
        }
    }

    /// The u32 code used in the binary tables (SPEC.md: 1 = f32, 2 = f16).
    #[must_use]
    pub const fn code(self) -> u32 {
        match self {
            ScalarType::F32 => 1,
            ScalarType::F16 => 2,
        }
    }

    /// Inverse of [`ScalarType::code`].
    #[must_use]
    pub const fn from_code(code: u32) -> Option<Self> {
        match code {
            1 => Some(ScalarType::F32),
            2 => Some(ScalarType::F16),
            _ => None,
        }
    }

    /// The name used in the metadata JSON (`"f32"`, `"f16"`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            ScalarType::F32 => "f32",
            ScalarType::F16 => "f16",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::ScalarType;

    #[test]
    fn codes_names_and_sizes_are_the_specs() {
        for (t, code, name, size) in [
            (ScalarType::F32, 1, "f32", 4),
            (ScalarType::F16, 2, "f16", 2),
        ] {
            assert_eq!((t.code(), t.name(), t.size()), (code, name, size));
            assert_eq!(ScalarType::from_code(code), Some(t));
        }
        assert_eq!(ScalarType::from_code(0), None);
        assert_eq!(ScalarType::from_code(3), None);
    }
}
