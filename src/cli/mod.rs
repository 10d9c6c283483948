//! The `kg` command line.
