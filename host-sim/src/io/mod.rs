//! Reading and writing the project's files.

pub mod config;

use std::path::Path;

use anyhow::{Context, Result};

/// Read `path` as a TOML file of `T`; an error names the file, what it
/// should have been (`what`, e.g. "an Eq. 3 model of `host-sim
/// identify-wrist --out`") and, for a parse error, the line and key.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path, what: &str) -> Result<T> {
    crate::output::note_input(path);
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    toml::from_str(&text).map_err(|e| {
        anyhow::anyhow!(
            "{}: not {what}: {}",
            path.display(),
            crate::log::toml_error(&text, &e)
        )
    })
}
