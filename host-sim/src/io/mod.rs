//! Reading and writing the project's files.

pub mod config;
