//! grip-digest: the one SHA-256 hex digest of grip. Pure (no I/O) and
//! depending on nothing but `sha2`, so that every layer can use it without
//! an arrow running the wrong way: the model file's checksum (grip-arte,
//! a pure crate that may import no I/O crate), the run metadata of MCAP logs
//! (grip-io, which must not pull in the DSP crate grip-arte for a hash) and
//! the dataset hashes of `grip train` all call [`sha256_hex`].
#![warn(missing_docs)]

use sha2::{Digest, Sha256};

/// Lower-case hex SHA-256 of `bytes` (64 characters).
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_digests() {
        // FIPS 180-2 test vectors
        assert_eq!(
            sha256_hex(b""),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
        );
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
