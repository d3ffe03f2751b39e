//! Tests of the avatar reader.
