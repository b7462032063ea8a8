//! Where the PostgreSQL server is and how to log in: the `[store]` URL, and the password
//! from (in this order) the URL itself, `password_file`, `$PGPASSWORD`, or the password file
//! libpq reads (`$PGPASSFILE`, else `~/.pgpass`), with libpq's rules: lines
//! `host:port:database:user:password`, `*` matches anything, `\` escapes `:` and `\`, the
//! first matching line wins, a Unix-socket connection matches the host `localhost`, and the
//! file is ignored unless only its owner can read it.

use postgres::config::Host;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// A parsed `url`, with the password resolved.
#[derive(Clone)]
pub struct ConnInfo {
    pub config: postgres::Config,
    /// The URL without its password, for messages and logs.
    pub shown: String,
}

impl std::fmt::Debug for ConnInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.shown)
    }
}

/// Why a `[store]` URL cannot be used (a configuration error: exit 78).
#[derive(Debug, thiserror::Error)]
pub enum ConnInfoError {
    #[error("[store] url: not a PostgreSQL URL ({0}); expected postgres://user@host:port/database")]
    BadUrl(String),
    #[error(
        "[store] url: the server's TLS is not supported by this build (sslmode={0}); use a Unix socket, loopback or a trusted network"
    )]
    Tls(String),
    #[error("[store] password_file {path}: {source}")]
    PasswordFile {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl ConnInfo {
    /// Parses `url` and finds the password. Never puts the password in `shown`.
    pub fn new(url: &str, password_file: Option<&Path>) -> Result<ConnInfo, ConnInfoError> {
        if !(url.starts_with("postgres://") || url.starts_with("postgresql://")) {
            return Err(ConnInfoError::BadUrl(
                "it must start with postgres://".into(),
            ));
        }
        let mut config =
            postgres::Config::from_str(url).map_err(|e| ConnInfoError::BadUrl(e.to_string()))?;
        if config.get_ssl_mode() == postgres::config::SslMode::Require {
            return Err(ConnInfoError::Tls("require".into()));
        }
        if config.get_user().is_none() {
            // libpq's default: the operating-system user name.
            if let Some(user) = std::env::var_os("USER").or_else(|| std::env::var_os("LOGNAME")) {
                config.user(user.to_string_lossy().as_ref());
            }
        }
        if config.get_connect_timeout().is_none() {
            config.connect_timeout(std::time::Duration::from_secs(10));
        }
        config.application_name("scanmill");
        let shown = shown_url(&config);
        if config.get_password().is_none() {
            if let Some(path) = password_file {
                let text = std::fs::read_to_string(path).map_err(|source| {
                    ConnInfoError::PasswordFile {
                        path: path.to_path_buf(),
                        source,
                    }
                })?;
                config.password(text.lines().next().unwrap_or("").as_bytes());
            } else if let Some(p) = std::env::var_os("PGPASSWORD") {
                config.password(p.to_string_lossy().as_bytes());
            } else if let Some(p) = pgpass_password(&config) {
                config.password(p.as_bytes());
            }
        }
        Ok(ConnInfo { config, shown })
    }
}

/// `postgres://user@host:port/db` (no password), for messages.
fn shown_url(config: &postgres::Config) -> String {
    let host = config
        .get_hosts()
        .first()
        .map(host_name)
        .unwrap_or_else(|| "localhost".into());
    let port = config.get_ports().first().copied().unwrap_or(5432);
    format!(
        "postgres://{}@{host}:{port}/{}",
        config.get_user().unwrap_or(""),
        config.get_dbname().unwrap_or("")
    )
}

fn host_name(h: &Host) -> String {
    match h {
        Host::Tcp(name) => name.clone(),
        Host::Unix(path) => path.to_string_lossy().into_owned(),
    }
}

/// The password `.pgpass` (or `$PGPASSFILE`) gives for this connection, if any.
fn pgpass_password(config: &postgres::Config) -> Option<String> {
    let path = match std::env::var_os("PGPASSFILE") {
        Some(p) => PathBuf::from(p),
        None => PathBuf::from(std::env::var_os("HOME")?).join(".pgpass"),
    };
    let meta = std::fs::metadata(&path).ok()?;
    if meta.permissions().mode() & 0o077 != 0 {
        tracing::warn!(
            "{}: ignored, it must be readable by its owner only (chmod 0600)",
            path.display()
        );
        return None;
    }
    let text = std::fs::read_to_string(&path).ok()?;
    let host = match config.get_hosts().first() {
        None | Some(Host::Unix(_)) => "localhost".to_string(),
        Some(Host::Tcp(name)) => name.clone(),
    };
    let port = config
        .get_ports()
        .first()
        .copied()
        .unwrap_or(5432)
        .to_string();
    let user = config.get_user().unwrap_or("");
    let db = config.get_dbname().unwrap_or(user);
    pgpass_lookup(&text, [&host, &port, db, user])
}

/// The first line of a pgpass file matching (host, port, database, user).
pub fn pgpass_lookup(text: &str, want: [&str; 4]) -> Option<String> {
    for line in text.lines() {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let fields = split_pgpass(line);
        if fields.len() != 5 {
            continue;
        }
        if fields[..4]
            .iter()
            .zip(want)
            .all(|(f, w)| f == "*" || f == w)
        {
            return Some(fields[4].clone());
        }
    }
    None
}

/// Splits a pgpass line at unescaped `:`, undoing `\:` and `\\`.
fn split_pgpass(line: &str) -> Vec<String> {
    let mut fields = vec![String::new()];
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match c {
            '\\' => {
                if let Some(n) = chars.next() {
                    fields.last_mut().expect("one").push(n);
                }
            }
            ':' if fields.len() < 5 => fields.push(String::new()),
            _ => fields.last_mut().expect("one").push(c),
        }
    }
    fields
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pgpass_first_match_wins_with_wildcards_and_escapes() {
        let text = "# comment\nother:5432:*:*:nope\nlocalhost:5433:lab:scan\\:mill:s\\\\e:cret\n*:*:*:*:fallback\n";
        assert_eq!(
            pgpass_lookup(text, ["localhost", "5433", "lab", "scan:mill"]).as_deref(),
            Some("s\\e:cret")
        );
        assert_eq!(
            pgpass_lookup(text, ["db1", "5432", "lab", "x"]).as_deref(),
            Some("fallback")
        );
        assert_eq!(pgpass_lookup("a:b:c:d:e\n", ["x", "b", "c", "d"]), None);
    }

    #[test]
    fn urls_are_checked_and_the_password_never_shown() {
        assert!(matches!(
            ConnInfo::new("mysql://x", None),
            Err(ConnInfoError::BadUrl(_))
        ));
        assert!(matches!(
            ConnInfo::new("postgres://u@h:notaport/db", None),
            Err(ConnInfoError::BadUrl(_))
        ));
        let c = ConnInfo::new("postgres://u:secret@db.lab:5433/scans", None).unwrap();
        assert_eq!(c.shown, "postgres://u@db.lab:5433/scans");
        assert_eq!(c.config.get_password(), Some(&b"secret"[..]));
        let dir = tempfile::tempdir().unwrap();
        let pw = dir.path().join("pw");
        std::fs::write(&pw, "fromfile\n").unwrap();
        let c = ConnInfo::new("postgres://u@db.lab/scans", Some(&pw)).unwrap();
        assert_eq!(c.config.get_password(), Some(&b"fromfile"[..]));
        assert!(matches!(
            ConnInfo::new("postgres://u@db.lab/scans", Some(&dir.path().join("none"))),
            Err(ConnInfoError::PasswordFile { .. })
        ));
    }
}
