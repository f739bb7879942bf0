//! Bearer tokens: read from a file (one a line), compared in constant time, never logged.
//!
//! A token is known by its SHA-256 ([`Owner`]): the server keeps and stores only the hashes,
//! compares the hash of a presented token with every known hash with
//! [`subtle::ConstantTimeEq`] and no early exit (the time taken does not depend on which
//! token matched, nor on how many leading bytes did), and a session belongs to the hash of
//! the token that made it.

use crate::errors::{ApiError, ServeError};
use axum::http::{HeaderMap, header};
use sha2::{Digest, Sha256};
use std::path::Path;
use subtle::ConstantTimeEq;

/// Shortest token accepted in a tokens file, characters.
pub const MIN_TOKEN_LEN: usize = 16;

/// Who owns a session: the SHA-256 of its token.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Owner(pub [u8; 32]);

impl std::fmt::Debug for Owner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // A short prefix of the hash: enough to tell owners apart in a log, useless to a reader.
        write!(f, "Owner({})", &self.hex()[..8])
    }
}

impl Owner {
    /// The hash as lowercase hex (how the database stores it).
    pub fn hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }

    /// The owner stored as [`Owner::hex`]; `None` for anything else.
    pub fn from_hex(s: &str) -> Option<Self> {
        if s.len() != 64 || !s.is_ascii() {
            return None;
        }
        let mut out = [0u8; 32];
        for (i, b) in out.iter_mut().enumerate() {
            *b = u8::from_str_radix(s.get(2 * i..2 * i + 2)?, 16).ok()?;
        }
        Some(Self(out))
    }
}

fn hash(token: &str) -> [u8; 32] {
    Sha256::digest(token.as_bytes()).into()
}

/// The accepted tokens (their hashes).
#[derive(Clone)]
pub struct Tokens {
    hashes: Vec<[u8; 32]>,
}

impl std::fmt::Debug for Tokens {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Tokens({} known)", self.hashes.len())
    }
}

impl Tokens {
    /// Reads a tokens file: one token a line, surrounding blanks ignored, empty lines and
    /// lines starting with `#` skipped; each at least [`MIN_TOKEN_LEN`] printable ASCII
    /// characters without spaces. Errors name the line, never the token.
    pub fn load(path: &Path) -> Result<Self, ServeError> {
        let text = std::fs::read_to_string(path).map_err(|source| ServeError::TokensFile {
            path: path.to_path_buf(),
            source,
        })?;
        let mut hashes = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let bad = |reason: &str| ServeError::BadToken {
                path: path.to_path_buf(),
                line: i + 1,
                reason: reason.into(),
            };
            if t.len() < MIN_TOKEN_LEN {
                return Err(bad(&format!(
                    "a token has at least {MIN_TOKEN_LEN} characters"
                )));
            }
            if !t.bytes().all(|b| b.is_ascii_graphic()) {
                return Err(bad("a token is printable ASCII without spaces"));
            }
            hashes.push(hash(t));
        }
        if hashes.is_empty() {
            return Err(ServeError::BadToken {
                path: path.to_path_buf(),
                line: 0,
                reason: "no token in the file".into(),
            });
        }
        Ok(Self { hashes })
    }

    /// Tokens given in code (tests, embedding).
    pub fn from_tokens<'a>(tokens: impl IntoIterator<Item = &'a str>) -> Self {
        Self {
            hashes: tokens.into_iter().map(hash).collect(),
        }
    }

    /// The owner of a presented token, if it is known: compared with every known token in
    /// constant time.
    pub fn check(&self, presented: &str) -> Option<Owner> {
        let h = hash(presented);
        let mut found = subtle::Choice::from(0u8);
        let mut owner = [0u8; 32];
        for known in &self.hashes {
            let eq = known.ct_eq(&h);
            found |= eq;
            // Select without branching on the comparison.
            for (o, k) in owner.iter_mut().zip(known) {
                *o = subtle::ConditionallySelectable::conditional_select(o, k, eq);
            }
        }
        bool::from(found).then_some(Owner(owner))
    }

    /// The owner of a request: its `Authorization: Bearer TOKEN` header checked.
    pub fn authenticate(&self, headers: &HeaderMap) -> Result<Owner, ApiError> {
        let value = headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .ok_or(ApiError::Unauthorized)?;
        let token = value
            .strip_prefix("Bearer ")
            .or_else(|| value.strip_prefix("bearer "))
            .ok_or(ApiError::Unauthorized)?;
        self.check(token.trim()).ok_or(ApiError::Unauthorized)
    }
}

/// A new random token (32 random bytes as 64 hex digits), for a tokens file.
pub fn generate_token() -> String {
    let bytes: [u8; 32] = rand::random();
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_tokens_match_and_others_do_not() {
        let tokens = Tokens::from_tokens(["aaaaaaaaaaaaaaaa-one", "bbbbbbbbbbbbbbbb-two"]);
        let one = tokens.check("aaaaaaaaaaaaaaaa-one").unwrap();
        let two = tokens.check("bbbbbbbbbbbbbbbb-two").unwrap();
        assert_ne!(one, two);
        assert_eq!(one, Owner(hash("aaaaaaaaaaaaaaaa-one")));
        assert!(tokens.check("aaaaaaaaaaaaaaaa-on").is_none());
        assert!(tokens.check("").is_none());
        assert_eq!(Owner::from_hex(&one.hex()), Some(one));
    }

    #[test]
    fn a_tokens_file_skips_comments_and_refuses_short_tokens_without_naming_them() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("tokens");
        std::fs::write(&p, "# phones\n\n  0123456789abcdef0123  \n").unwrap();
        let t = Tokens::load(&p).unwrap();
        assert!(t.check("0123456789abcdef0123").is_some());
        std::fs::write(&p, "0123456789abcdef0123\nshort-secret\n").unwrap();
        let e = Tokens::load(&p).unwrap_err().to_string();
        assert!(e.contains("line 2"), "{e}");
        assert!(!e.contains("short-secret"), "{e}");
    }

    #[test]
    fn generated_tokens_are_accepted_by_a_file() {
        let t = generate_token();
        assert_eq!(t.len(), 64);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("tokens");
        std::fs::write(&p, &t).unwrap();
        assert!(Tokens::load(&p).unwrap().check(&t).is_some());
    }
}
