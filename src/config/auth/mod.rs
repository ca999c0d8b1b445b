//! The auth file of `qrpose serve --auth-file FILE` (docs/security.md): who may call the
//! service, by bearer token, and with which scopes.
//!
//! ```yaml
//! clients:
//!   - name: robot-7               # in logs and metric labels; never the token
//!     token_sha256: "9f86d0…"     # hex SHA-256 of the token, never the token itself
//!     scopes: [pose]              # pose | site | admin | metrics
//! ```
//!
//! Rules, checked at load (a refused file names its line): `name` is 1 to 64 letters,
//! digits, `.`, `_` or `-`, starting with a letter or digit, and unique (it becomes a metric
//! label value, so the set of labels is the set of names in the file); `token_sha256` is 64
//! hex digits, unique (two clients cannot share a token); `scopes` is a non-empty list;
//! no other keys. An empty `clients: []` is valid and locks every protected route.
//!
//! Tokens are made by `qrpose auth add` ([`new_token`]): `qrp_` and 43 base64url
//! characters, 256 random bits from the operating system. The file holds their SHA-256, a
//! fast hash: a slow one (argon2, scrypt) protects secrets that people choose and could be
//! guessed, and would cost every request milliseconds; 256 random bits cannot be found from
//! their digest. A presented token is hashed once and compared with every client's digest
//! in constant time ([`Clients::identify`]).

use base64::Engine;
use serde::Deserialize;
use sha2::{Digest, Sha256};
use std::fmt;
use std::path::{Path, PathBuf};
use subtle::ConstantTimeEq;

/// What a client may call. Each protected route needs exactly one scope
/// (`http::auth::access_for`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Scope {
    /// `/v1/pose/*`, `/v1/stream`, `/v1/calibrate`: estimating poses.
    Pose,
    /// `GET /v1/site`: reading the loaded site.
    Site,
    /// `POST /v1/site/reload`: changing what the service serves.
    Admin,
    /// `GET /metrics`.
    Metrics,
}

impl Scope {
    /// Every scope, in the order of the documentation.
    pub const ALL: [Scope; 4] = [Scope::Pose, Scope::Site, Scope::Admin, Scope::Metrics];

    /// The name, as in the file and in `WWW-Authenticate`'s `scope`.
    pub fn as_str(self) -> &'static str {
        match self {
            Scope::Pose => "pose",
            Scope::Site => "site",
            Scope::Admin => "admin",
            Scope::Metrics => "metrics",
        }
    }

    fn bit(self) -> u8 {
        match self {
            Scope::Pose => 1,
            Scope::Site => 2,
            Scope::Admin => 4,
            Scope::Metrics => 8,
        }
    }
}

impl fmt::Display for Scope {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A set of scopes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Scopes(u8);

impl Scopes {
    /// Whether `scope` is in the set.
    pub fn contains(self, scope: Scope) -> bool {
        self.0 & scope.bit() != 0
    }

    /// The scopes in the set, in [`Scope::ALL`]'s order.
    pub fn iter(self) -> impl Iterator<Item = Scope> {
        Scope::ALL.into_iter().filter(move |s| self.contains(*s))
    }

    /// Whether the set is empty.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

impl FromIterator<Scope> for Scopes {
    fn from_iter<I: IntoIterator<Item = Scope>>(iter: I) -> Self {
        Self(iter.into_iter().fold(0, |bits, s| bits | s.bit()))
    }
}

impl fmt::Display for Scopes {
    /// `pose, site`, as in the file's flow list.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names: Vec<&str> = self.iter().map(Scope::as_str).collect();
        f.write_str(&names.join(", "))
    }
}

/// One client of the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Client {
    name: String,
    token_sha256: [u8; 32],
    scopes: Scopes,
}

impl Client {
    /// The client's name: what logs and metric labels show.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// What it may call.
    pub fn scopes(&self) -> Scopes {
        self.scopes
    }
}

/// Why an auth file was refused: `FILE[:LINE]: reason`, like a refused site file.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}{}: {reason}", file.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct AuthFileError {
    /// The file.
    pub file: PathBuf,
    /// 1-based line, when the refusal points at one.
    pub line: Option<usize>,
    /// What is wrong.
    pub reason: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AuthFile {
    clients: Vec<ClientEntry>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClientEntry {
    name: String,
    token_sha256: String,
    scopes: Vec<Scope>,
}

/// The clients of one auth file, as loaded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Clients {
    clients: Vec<Client>,
    file_sha256: String,
}

impl Clients {
    /// Reads and validates the auth file at `path`.
    ///
    /// # Errors
    /// [`AuthFileError`] with the file, the line when known and the reason.
    pub fn load(path: &Path) -> Result<Self, AuthFileError> {
        let refuse = |reason: String| AuthFileError {
            file: path.to_owned(),
            line: None,
            reason,
        };
        let bytes = std::fs::read(path).map_err(|e| refuse(format!("cannot read: {e}")))?;
        let text = String::from_utf8(bytes).map_err(|e| refuse(format!("not UTF-8: {e}")))?;
        Self::parse(&text, path)
    }

    /// Validates the auth file text `text`, read from `path` (named in errors).
    ///
    /// # Errors
    /// As [`Clients::load`].
    pub fn parse(text: &str, path: &Path) -> Result<Self, AuthFileError> {
        let refuse = |line: Option<usize>, reason: String| AuthFileError {
            file: path.to_owned(),
            line,
            reason,
        };
        let file: AuthFile = serde_norway::from_str(text)
            .map_err(|e| refuse(e.location().map(|l| l.line()), e.to_string()))?;
        let mut clients: Vec<Client> = Vec::with_capacity(file.clients.len());
        for (index, entry) in file.clients.into_iter().enumerate() {
            let earlier = clients.iter().filter(|c| c.name == entry.name).count();
            let line = line_of(text, &entry.name, earlier);
            let at = |reason: String| refuse(line, format!("clients[{index}]: {reason}"));
            check_name(&entry.name).map_err(at)?;
            let token_sha256 = parse_digest(&entry.token_sha256).map_err(at)?;
            let scopes: Scopes = entry.scopes.iter().copied().collect();
            if scopes.is_empty() {
                return Err(at(format!(
                    "client {:?} has no scope: give one or more of pose, site, admin, metrics",
                    entry.name
                )));
            }
            if clients.iter().any(|c| c.name == entry.name) {
                return Err(at(format!("the name {:?} is given twice", entry.name)));
            }
            if let Some(twin) = clients.iter().find(|c| c.token_sha256 == token_sha256) {
                return Err(at(format!(
                    "client {:?} has the token of {:?}: each client needs its own token",
                    entry.name, twin.name
                )));
            }
            clients.push(Client {
                name: entry.name,
                token_sha256,
                scopes,
            });
        }
        Ok(Self {
            clients,
            file_sha256: hex(&Sha256::digest(text.as_bytes())),
        })
    }

    /// The client whose token this is, if any. The token is hashed once and its digest
    /// compared with every client's, each comparison in constant time, none cut short.
    pub fn identify(&self, token: &str) -> Option<&Client> {
        let digest = token_sha256(token);
        self.clients.iter().fold(None, |found, client| {
            let same = bool::from(client.token_sha256.ct_eq(&digest));
            if same { Some(client) } else { found }
        })
    }

    /// The clients, in the file's order.
    pub fn iter(&self) -> impl Iterator<Item = &Client> {
        self.clients.iter()
    }

    /// Number of clients.
    pub fn len(&self) -> usize {
        self.clients.len()
    }

    /// Whether the file names no client (every protected route is then locked).
    pub fn is_empty(&self) -> bool {
        self.clients.is_empty()
    }

    /// Hex SHA-256 of the file's bytes, to tell which version is loaded.
    pub fn file_sha256_hex(&self) -> &str {
        &self.file_sha256
    }
}

/// The 1-based line of the `nth` (0-based) `name:` entry with this value, if any (block or
/// flow style).
fn line_of(text: &str, name: &str, nth: usize) -> Option<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| {
            l.split_once("name:").is_some_and(|(_, v)| {
                let value = v.split([',', '}']).next().unwrap_or_default();
                value.trim().trim_matches(['"', '\'']) == name
            })
        })
        .nth(nth)
        .map(|(i, _)| i + 1)
}

/// Longest client name, characters.
pub const MAX_NAME_LEN: usize = 64;

/// Checks a client name: 1 to [`MAX_NAME_LEN`] letters, digits, `.`, `_`, `-`, starting with a
/// letter or digit.
///
/// # Errors
/// Why the name is refused.
pub fn check_name(name: &str) -> Result<(), String> {
    let bytes = name.as_bytes();
    let first_ok = bytes.first().is_some_and(u8::is_ascii_alphanumeric);
    let rest_ok = bytes
        .iter()
        .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(b));
    if first_ok && rest_ok && bytes.len() <= MAX_NAME_LEN {
        Ok(())
    } else {
        Err(format!(
            "the client name {name:?} must be 1 to {MAX_NAME_LEN} letters, digits, '.', '_' or \
             '-', starting with a letter or digit"
        ))
    }
}

fn parse_digest(hex_digest: &str) -> Result<[u8; 32], String> {
    let refuse = || {
        format!(
            "token_sha256 must be 64 hex digits (the SHA-256 of the token, as `qrpose auth add` \
             prints it), got {} characters",
            hex_digest.chars().count()
        )
    };
    if hex_digest.len() != 64 {
        return Err(refuse());
    }
    let mut digest = [0u8; 32];
    for (byte, pair) in digest.iter_mut().zip(hex_digest.as_bytes().chunks_exact(2)) {
        let text = std::str::from_utf8(pair).map_err(|_| refuse())?;
        *byte = u8::from_str_radix(text, 16).map_err(|_| refuse())?;
    }
    Ok(digest)
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The SHA-256 of a token's UTF-8 bytes.
pub fn token_sha256(token: &str) -> [u8; 32] {
    Sha256::digest(token.as_bytes()).into()
}

/// The SHA-256 of a token as 64 lowercase hex digits, as the file holds it.
pub fn token_sha256_hex(token: &str) -> String {
    hex(&token_sha256(token))
}

/// The prefix of every token `qrpose auth add` makes (so that secret scanners and people
/// recognise one).
pub const TOKEN_PREFIX: &str = "qrp_";

/// A fresh token: [`TOKEN_PREFIX`] and 32 bytes of the operating system's random generator
/// in base64url without padding (43 characters). Every character is valid in a header and
/// in a WebSocket subprotocol name.
pub fn new_token() -> String {
    use rand::RngCore;
    let mut bytes = [0u8; 32];
    rand::rngs::OsRng.fill_bytes(&mut bytes);
    format!(
        "{TOKEN_PREFIX}{}",
        base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(bytes)
    )
}

/// The file's entry for a client, on one line (YAML flow style), to put under `clients:`.
pub fn entry_line(name: &str, token: &str, scopes: Scopes) -> String {
    format!(
        "  - {{name: {name}, token_sha256: \"{}\", scopes: [{scopes}]}}",
        token_sha256_hex(token)
    )
}

#[cfg(test)]
mod tests;
