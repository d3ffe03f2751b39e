//! The `--nats` value: one or more comma-separated server URLs, and the credentials their user
//! info carries. async-nats 0.50 parses a URL's user info but never sends it, and takes one URL
//! per string, so both are done here before connecting.

use crate::ClusterError;
use async_nats::ServerAddr;

/// Credentials from a URL's user info.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Credentials {
    /// No user info.
    None,
    /// `nats://TOKEN@host`: the server's `authorization { token }` (or `--auth`).
    Token(String),
    /// `nats://USER:PASS@host`: a user of the server's `authorization { users }` (or `--user`).
    UserPassword(String, String),
}

/// The servers of `urls` (`nats://` or `tls://`, comma-separated, the port 4222 when left out)
/// and the credentials of the first that has user info; all that carry user info must agree.
pub(crate) fn parse(urls: &str) -> Result<(Vec<ServerAddr>, Credentials), ClusterError> {
    let bad = |message: String| ClusterError::Connect {
        url: redact(urls),
        message,
    };
    let mut servers = Vec::new();
    let mut credentials = Credentials::None;
    for part in urls.split(',').map(str::trim) {
        if part.is_empty() {
            return Err(bad("an empty server URL in the list".into()));
        }
        let addr: ServerAddr = part
            .parse()
            .map_err(|e| bad(format!("`{}`: {e}", redact(part))))?;
        let found = match (addr.username(), addr.password()) {
            (None, _) => Credentials::None,
            (Some(t), None) => Credentials::Token(decode(t)),
            (Some(u), Some(p)) => Credentials::UserPassword(decode(u), decode(p)),
        };
        if found != Credentials::None {
            if credentials != Credentials::None && credentials != found {
                return Err(bad("the URLs carry different credentials".into()));
            }
            credentials = found;
        }
        servers.push(addr);
    }
    Ok((servers, credentials))
}

/// `urls` with every URL's user info (a token or password) shown as `***`, for messages.
pub fn redact(urls: &str) -> String {
    urls.split(',')
        .map(|part| {
            let after = part.find("://").map_or(0, |i| i + 3);
            let host_from = part[after..].find('/').map_or(part.len(), |i| after + i);
            match part[after..host_from].rfind('@') {
                Some(at) => format!("{}***{}", &part[..after], &part[after + at..]),
                None => part.to_string(),
            }
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// Percent-decodes a URL's user or password (`%40` is `@`); malformed escapes stay as they are.
fn decode(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match (
            b.get(i),
            b.get(i + 1).copied().and_then(hex),
            b.get(i + 2).copied().and_then(hex),
        ) {
            (Some(b'%'), Some(h), Some(l)) => {
                out.push((h * 16 + l) as u8);
                i += 3;
            }
            (Some(&c), _, _) => {
                out.push(c);
                i += 1;
            }
            (None, _, _) => break,
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok(urls: &str) -> (Vec<ServerAddr>, Credentials) {
        match parse(urls) {
            Ok(v) => v,
            Err(e) => panic!("{urls}: {e}"),
        }
    }

    #[test]
    fn one_url_without_credentials() {
        let (servers, creds) = ok("nats://127.0.0.1:4222");
        assert_eq!(servers.len(), 1);
        assert_eq!((servers[0].host(), servers[0].port()), ("127.0.0.1", 4222));
        assert!(!servers[0].tls_required());
        assert_eq!(creds, Credentials::None);
    }

    #[test]
    fn a_list_of_servers_with_tls_and_a_token() {
        let (servers, creds) = ok("tls://s3cr%40t@a.example:4443, nats://b.example,c.example:5222");
        let got: Vec<_> = servers
            .iter()
            .map(|s| (s.host().to_string(), s.port(), s.tls_required()))
            .collect();
        assert_eq!(
            got,
            [
                ("a.example".to_string(), 4443, true),
                ("b.example".to_string(), 4222, false),
                ("c.example".to_string(), 5222, false),
            ]
        );
        assert_eq!(creds, Credentials::Token("s3cr@t".into()));
    }

    #[test]
    fn user_and_password_and_their_agreement() {
        let (_, creds) = ok("nats://worker:pw@a:4222,nats://worker:pw@b:4222,nats://c:4222");
        assert_eq!(
            creds,
            Credentials::UserPassword("worker".into(), "pw".into())
        );
        let e = parse("nats://worker:pw@a:4222,nats://other:pw@b:4222");
        assert!(
            matches!(&e, Err(ClusterError::Connect { message, .. }) if message.contains("different credentials")),
            "{e:?}"
        );
    }

    #[test]
    fn a_bad_or_empty_url_is_named() {
        for urls in ["nats://a:4222,", "nats://a:notaport", "http://a:80"] {
            match parse(urls) {
                Err(ClusterError::Connect { url, message }) => {
                    assert_eq!(url, redact(urls));
                    assert!(!message.is_empty());
                }
                other => panic!("{urls}: {other:?}"),
            }
        }
    }

    #[test]
    fn credentials_never_reach_a_message() {
        assert_eq!(
            redact("tls://tok@a:1,nats://b:2, nats://u:p@c:3/x@y"),
            "tls://***@a:1,nats://b:2, nats://***@c:3/x@y"
        );
        match parse("nats://u:secret@a:notaport") {
            Err(e) => assert!(!e.to_string().contains("secret"), "{e}"),
            Ok(_) => panic!("a bad port was taken"),
        }
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(decode("a%2Fb%3a%zz%4"), "a/b:%zz%4");
        assert_eq!(decode(""), "");
    }
}
