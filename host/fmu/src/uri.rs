//! The importer's `fmuResourceLocation` (a `file:` URI, RFC 8089) as a local path.

use std::path::PathBuf;

/// The local directory named by `uri`: `file:///abs/path`, `file:/abs/path` or
/// `file://localhost/abs/path`, percent-escapes decoded. A plain absolute path is taken as
/// it is (some importers pass one).
pub fn resource_dir(uri: &str) -> Result<PathBuf, String> {
    let path = if let Some(rest) = strip_prefix_ignore_case(uri, "file:") {
        let rest = if let Some(after) = rest.strip_prefix("//") {
            // An authority: empty or `localhost` is this machine.
            let (host, path) = after.split_at(after.find('/').unwrap_or(after.len()));
            if !(host.is_empty() || host.eq_ignore_ascii_case("localhost")) {
                return Err(format!(
                    "the resource location `{uri}` is on another host (`{host}`); the FMU reads its resources from a local directory"
                ));
            }
            path
        } else {
            rest
        };
        decode(rest)
            .ok_or_else(|| format!("the resource location `{uri}` has a bad percent-escape"))?
    } else if uri.starts_with('/') {
        uri.to_string()
    } else {
        return Err(format!(
            "the resource location `{uri}` is not a file: URI (expected file:///path/to/resources)"
        ));
    };
    if !path.starts_with('/') {
        return Err(format!(
            "the resource location `{uri}` is not an absolute path"
        ));
    }
    Ok(PathBuf::from(path))
}

fn strip_prefix_ignore_case<'a>(s: &'a str, prefix: &str) -> Option<&'a str> {
    let head = s.get(..prefix.len())?;
    head.eq_ignore_ascii_case(prefix)
        .then(|| &s[prefix.len()..])
}

/// `s` with `%XX` escapes decoded (as UTF-8); `None` for a malformed escape.
fn decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_uris_of_every_common_form_name_the_directory() {
        let want = PathBuf::from("/tmp/my fmu/resources");
        for uri in [
            "file:///tmp/my%20fmu/resources",
            "file:/tmp/my%20fmu/resources",
            "file://localhost/tmp/my%20fmu/resources",
            "FILE:///tmp/my%20fmu/resources",
            "/tmp/my fmu/resources",
        ] {
            assert_eq!(resource_dir(uri).as_deref(), Ok(want.as_path()), "{uri}");
        }
        assert_eq!(
            resource_dir("file:///t/%C3%A9").as_deref(),
            Ok(std::path::Path::new("/t/\u{e9}"))
        );
    }

    #[test]
    fn other_hosts_schemes_and_bad_escapes_are_refused_with_the_uri() {
        for uri in [
            "file://server/share/resources",
            "http://example.com/resources",
            "resources",
            "file:///tmp/%zz",
            "file:///tmp/%4",
            "file:relative/path",
        ] {
            let e = resource_dir(uri).expect_err(uri);
            assert!(e.contains(uri), "{e}");
        }
    }
}
