//! `[web]`: the dashboard's configuration and its validation.
//!
//! Rule: the dashboard is read-only but shows file names, paths and error texts, so it
//! listens on loopback unless the operator says how it is protected: a `token` (every
//! request then needs it, as `Authorization: Bearer …` or as the password of HTTP Basic
//! authentication) or `behind_reverse_proxy = true` (the proxy in front authenticates and
//! terminates TLS, and the address is reachable from the proxy alone).

use serde::Deserialize;
use std::net::SocketAddr;

fn default_listen() -> String {
    "127.0.0.1:8640".into()
}

/// The shortest token accepted: guessing 16 random characters is out of reach.
pub const MIN_TOKEN_CHARS: usize = 16;

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WebConfig {
    /// Serve the dashboard and `/metrics`. Off by default.
    #[serde(default)]
    pub enabled: bool,
    /// `address:port` to listen on.
    #[serde(default = "default_listen")]
    pub listen: String,
    /// When set, every request must carry it (bearer token, or Basic password).
    #[serde(default)]
    pub token: Option<String>,
    /// The operator's acknowledgement that a reverse proxy in front of a non-loopback
    /// address authenticates the users.
    #[serde(default)]
    pub behind_reverse_proxy: bool,
}

impl Default for WebConfig {
    fn default() -> Self {
        WebConfig {
            enabled: false,
            listen: default_listen(),
            token: None,
            behind_reverse_proxy: false,
        }
    }
}

impl WebConfig {
    /// The address to bind, if `listen` is one.
    pub fn address(&self) -> Option<SocketAddr> {
        self.listen.trim().parse().ok()
    }

    /// Every problem with `[web]` (checked even while it is disabled, so that switching it
    /// on later cannot meet a surprise).
    pub fn validate(&self) -> Vec<String> {
        let mut problems = Vec::new();
        let shown = crate::text::bounded(&self.listen, 80);
        let Some(addr) = self.address() else {
            problems.push(format!(
                "web.listen must be an address and port such as \"127.0.0.1:8640\", not \"{shown}\""
            ));
            return problems;
        };
        if let Some(token) = &self.token {
            let printable = token.chars().all(|c| c.is_ascii_graphic());
            if token.chars().count() < MIN_TOKEN_CHARS || !printable {
                problems.push(format!(
                    "web.token must be at least {MIN_TOKEN_CHARS} printable ASCII characters without spaces"
                ));
            }
        }
        if !addr.ip().is_loopback() && self.token.is_none() && !self.behind_reverse_proxy {
            problems.push(format!(
                "web.listen {addr} is not a loopback address: set web.token, or web.behind_reverse_proxy = true \
                 when a proxy in front authenticates the users (docs/service.md \"Web dashboard and metrics\")"
            ));
        }
        problems
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn web(listen: &str, token: Option<&str>, proxy: bool) -> WebConfig {
        WebConfig {
            enabled: true,
            listen: listen.into(),
            token: token.map(String::from),
            behind_reverse_proxy: proxy,
        }
    }

    #[test]
    fn loopback_needs_nothing_else() {
        assert!(web("127.0.0.1:8640", None, false).validate().is_empty());
        assert!(web("[::1]:0", None, false).validate().is_empty());
    }

    #[test]
    fn other_addresses_need_a_token_or_a_proxy() {
        let p = web("0.0.0.0:8640", None, false).validate();
        assert_eq!(p.len(), 1, "{p:?}");
        assert!(p[0].contains("not a loopback address"), "{p:?}");
        assert!(
            web("0.0.0.0:8640", Some("0123456789abcdef"), false)
                .validate()
                .is_empty()
        );
        assert!(web("192.0.2.1:80", None, true).validate().is_empty());
    }

    #[test]
    fn bad_listen_and_weak_token_are_reported() {
        let p = web("localhost", None, false).validate();
        assert!(p[0].contains("web.listen"), "{p:?}");
        let p = web("127.0.0.1:1", Some("short"), false).validate();
        assert!(p[0].contains("web.token"), "{p:?}");
        let p = web("127.0.0.1:1", Some("has a space in it ok"), false).validate();
        assert!(p[0].contains("web.token"), "{p:?}");
    }
}
