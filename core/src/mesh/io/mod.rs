//! Readers and writers for sequence layouts.
