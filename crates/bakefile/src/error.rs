//! The one error type of this crate.

use std::path::PathBuf;

/// Everything that can go wrong while encoding, decoding, reading, writing or merging a bake.
///
/// Decoding never panics: every malformed input maps to one of these variants.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BakeFileError {
    /// An error that happened while reading or writing a named file.
    #[error("{}: {source}", path.display())]
    File {
        /// The file being read or written.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: Box<BakeFileError>,
    },
    /// An operating-system I/O error.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The input ends before a structure it announces.
    #[error("truncated: needed {needed} bytes, have {available}")]
    Truncated {
        /// Bytes the structure needs.
        needed: u64,
        /// Bytes actually present.
        available: u64,
    },
    /// The first 8 bytes are not `PRTBAKE\0`.
    #[error("not a PRT bake file: magic bytes {found:02x?}")]
    BadMagic {
        /// The 8 bytes found (fewer if the input is shorter).
        found: Vec<u8>,
    },
    /// The major format version is not one this reader understands.
    #[error(
        "unsupported format version {major}.{minor} (this reader reads major version {supported})"
    )]
    UnsupportedVersion {
        /// Major version in the file.
        major: u32,
        /// Minor version in the file.
        minor: u32,
        /// The major version this reader reads.
        supported: u32,
    },
    /// The file sets a required flag (file header or section) this reader does not know.
    #[error("unsupported required flags {flags:#010x} in {location}")]
    UnsupportedFlags {
        /// Where: "header" or a section name.
        location: String,
        /// The unknown flag bits.
        flags: u32,
    },
    /// A stored CRC-32 does not match the bytes.
    #[error("checksum mismatch in {section}: stored {stored:#010x}, computed {computed:#010x}")]
    ChecksumMismatch {
        /// "header" (file header + section table) or a section name such as `XFER#7`.
        section: String,
        /// CRC stored in the file.
        stored: u32,
        /// CRC of the bytes present.
        computed: u32,
    },
    /// Two places that must agree on a number do not.
    #[error("inconsistent counts: {what}: expected {expected}, found {found}")]
    InconsistentCounts {
        /// What was compared.
        what: String,
        /// The value implied by the other place.
        expected: u64,
        /// The value found.
        found: u64,
    },
    /// A NaN or infinity in numeric data.
    #[error("non-finite value in {section} at index {index}")]
    NonFinite {
        /// The section or in-memory array holding it.
        section: String,
        /// Index of the scalar within that array.
        index: u64,
    },
    /// A value that is finite in f32 but beyond the f16 range (|x| > 65504 after rounding).
    #[error("value {value} in {section} at index {index} is outside the f16 range")]
    OutOfF16Range {
        /// Where the value is.
        section: String,
        /// Index of the scalar within that array.
        index: u64,
        /// The value.
        value: f32,
    },
    /// Two sections (or a section and the header/section table) share bytes.
    #[error("sections overlap: {first} and {second}")]
    Overlap {
        /// One region.
        first: String,
        /// The other region.
        second: String,
    },
    /// A section offset is not a multiple of the payload alignment.
    #[error("section {section} at offset {offset} is not aligned to {alignment} bytes")]
    Misaligned {
        /// Section name.
        section: String,
        /// Its offset.
        offset: u64,
        /// Required alignment.
        alignment: u64,
    },
    /// A section extends past the end of the file.
    #[error("section {section} (offset {offset}, length {length}) extends past the end of the {file_size}-byte file")]
    OutOfBounds {
        /// Section name.
        section: String,
        /// Its offset.
        offset: u64,
        /// Its length.
        length: u64,
        /// The file size.
        file_size: u64,
    },
    /// A section that must be present once is missing.
    #[error("missing required section {0}")]
    MissingSection(String),
    /// A section that may be present once appears twice.
    #[error("section {0} appears more than once")]
    DuplicateSection(String),
    /// A section with an unknown tag is marked as required.
    #[error("unknown required section {0}")]
    UnknownRequiredSection(String),
    /// A field holds a value outside its domain (an unknown enum code, bad UTF-8, ...).
    #[error("invalid {field}: {reason}")]
    InvalidValue {
        /// The field.
        field: String,
        /// Why it is invalid.
        reason: String,
    },
    /// The metadata JSON is malformed or disagrees with the binary tables.
    #[error("metadata: {0}")]
    Metadata(String),
    /// The in-memory bake handed to the encoder breaks a rule of the format.
    #[error("invalid bake: {0}")]
    InvalidBake(String),
    /// Shards cannot be merged.
    #[error("cannot merge shards: {0}")]
    Merge(String),
    /// A file broke rule `rule` of SPEC.md §4 ("What a reader must check"): the error, with
    /// the rule named after it.
    #[error("{source} (SPEC §4 rule {rule})")]
    Rule {
        /// The rule's number in SPEC.md §4, 1 to 11.
        rule: u8,
        /// What was wrong.
        #[source]
        source: Box<BakeFileError>,
    },
}

impl BakeFileError {
    /// Attaches a file path to this error (unless it already names one).
    #[must_use]
    pub fn in_file(self, path: impl Into<PathBuf>) -> Self {
        match self {
            e @ BakeFileError::File { .. } => e,
            e => BakeFileError::File {
                path: path.into(),
                source: Box::new(e),
            },
        }
    }

    /// The error without its file context and rule: `File { source, .. }` and
    /// `Rule { source, .. }` unwrap to `source`.
    #[must_use]
    pub fn root(&self) -> &BakeFileError {
        match self {
            BakeFileError::File { source, .. } | BakeFileError::Rule { source, .. } => {
                source.root()
            }
            e => e,
        }
    }

    /// [`BakeFileError::root`] by value.
    #[must_use]
    pub fn into_root(self) -> BakeFileError {
        match self {
            BakeFileError::File { source, .. } | BakeFileError::Rule { source, .. } => {
                source.into_root()
            }
            e => e,
        }
    }

    /// The SPEC.md §4 rule the error breaks, when it is a refusal of a file's contents.
    #[must_use]
    pub fn rule(&self) -> Option<u8> {
        match self {
            BakeFileError::File { source, .. } => source.rule(),
            BakeFileError::Rule { rule, .. } => Some(*rule),
            _ => None,
        }
    }

    /// Names rule `rule` of SPEC.md §4 after the error, unless it already names one (the
    /// innermost, most specific, rule wins; a file context stays outermost).
    #[must_use]
    pub fn in_rule(self, rule: u8) -> Self {
        match self {
            e @ BakeFileError::Rule { .. } => e,
            BakeFileError::File { path, source } => BakeFileError::File {
                path,
                source: Box::new(source.in_rule(rule)),
            },
            e => BakeFileError::Rule {
                rule,
                source: Box::new(e),
            },
        }
    }
}

pub(crate) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> BakeFileError {
    BakeFileError::InvalidValue {
        field: field.into(),
        reason: reason.into(),
    }
}

pub(crate) fn inconsistent(what: impl Into<String>, expected: u64, found: u64) -> BakeFileError {
    BakeFileError::InconsistentCounts {
        what: what.into(),
        expected,
        found,
    }
}
