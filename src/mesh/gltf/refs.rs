//! The files a `.gltf` names beside itself: its external buffers and images. The watcher
//! needs them to know when a glTF scan set is complete (the loader reads them itself, in
//! [`super::read()`]); nothing else of the document is looked at here.
//!
//! The document is streamed: every value but `buffers[].uri` and `images[].uri` is skipped
//! unread, and a `data:` URI is recognised and dropped without being kept, so memory stays
//! at the largest single string however big the file is.

use serde::Deserialize;
use serde::de::{Deserializer, Visitor};
use std::io::Read;

/// What a referenced file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefRole {
    /// A `.bin` (or any) buffer: vertex and index data.
    Buffer,
    /// An image: a texture.
    Image,
}

/// One file a `.gltf` names: its file name as the loader would read it (percent escapes
/// decoded, `\` as `/`), relative to the `.gltf`'s folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExternalRef {
    pub role: RefRole,
    pub name: String,
}

/// The external buffers then images of the glTF JSON `reader` yields, in document order,
/// each once. `data:` URIs and images held in buffer views name no file and are skipped.
/// A URI with another scheme (`http:`, `file:`, …) is an error: the loader refuses it too.
pub fn external_refs(reader: impl Read) -> Result<Vec<ExternalRef>, String> {
    let doc: Doc = serde_json::from_reader(reader).map_err(|e| format!("not glTF JSON: {e}"))?;
    let mut out: Vec<ExternalRef> = Vec::new();
    let tagged = |role, list: Vec<Item>| list.into_iter().map(move |i| (role, i.uri));
    for (role, uri) in
        tagged(RefRole::Buffer, doc.buffers).chain(tagged(RefRole::Image, doc.images))
    {
        let Uri::File(uri) = uri else { continue };
        let name = file_name(&uri).map_err(|why| {
            let what = match role {
                RefRole::Buffer => "buffer",
                RefRole::Image => "image",
            };
            format!("{what} URI {}: {why}", crate::text::escape_str(&uri))
        })?;
        if !out.iter().any(|r| r.name == name) {
            out.push(ExternalRef { role, name });
        }
    }
    Ok(out)
}

/// The file name a relative URI means; the one rule the loader and the watcher share.
pub(super) fn file_name(uri: &str) -> Result<String, String> {
    if uri.contains(':') {
        return Err("only relative file names and data: URIs are read".into());
    }
    Ok(crate::mesh::texture::normalise_name(&percent_decode(uri)?))
}

/// `%XX` escapes of a relative URI decoded into the file name it means.
fn percent_decode(uri: &str) -> Result<String, String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = uri.get(i + 1..i + 3).ok_or("a % escape cut short")?;
            out.push(u8::from_str_radix(hex, 16).map_err(|_| format!("bad escape %{hex}"))?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| "the decoded URI is not UTF-8".to_string())
}

/// The two arrays that name files; every other member is skipped by serde.
#[derive(Deserialize)]
struct Doc {
    #[serde(default)]
    buffers: Vec<Item>,
    #[serde(default)]
    images: Vec<Item>,
}

#[derive(Deserialize)]
struct Item {
    #[serde(default)]
    uri: Uri,
}

/// A URI as far as the watcher cares: a file, or nothing to wait for.
#[derive(Default)]
enum Uri {
    #[default]
    None,
    File(String),
}

impl<'de> Deserialize<'de> for Uri {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Uri, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Uri;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a URI string")
            }
            // Borrowed from the parser's scratch buffer: a data URI is never copied.
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<Uri, E> {
                Ok(if s.starts_with("data:") {
                    Uri::None
                } else {
                    Uri::File(s.to_string())
                })
            }
        }
        d.deserialize_str(V)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refs(json: &str) -> Result<Vec<ExternalRef>, String> {
        external_refs(json.as_bytes())
    }

    #[test]
    fn buffers_then_images_decoded_and_once_each() {
        let got = refs(
            r#"{"asset":{"version":"2.0"},
                "images":[{"uri":"face%20photo.jpg"},{"bufferView":3},{"uri":"sub\\tex.png"}],
                "buffers":[{"uri":"mesh.bin","byteLength":8},{"uri":"mesh.bin","byteLength":8},
                           {"uri":"data:application/octet-stream;base64,AAAA","byteLength":3}]}"#,
        )
        .unwrap();
        let names: Vec<(RefRole, &str)> = got.iter().map(|r| (r.role, r.name.as_str())).collect();
        assert_eq!(
            names,
            [
                (RefRole::Buffer, "mesh.bin"),
                (RefRole::Image, "face photo.jpg"),
                (RefRole::Image, "sub/tex.png"),
            ]
        );
    }

    #[test]
    fn a_document_without_files_names_none() {
        assert_eq!(refs(r#"{"asset":{"version":"2.0"}}"#).unwrap(), []);
    }

    #[test]
    fn other_schemes_and_bad_json_are_errors() {
        let e = refs(r#"{"buffers":[{"uri":"https://example.org/a.bin"}]}"#).unwrap_err();
        assert!(e.contains("buffer URI") && e.contains("relative"), "{e}");
        let e = refs(r#"{"images":[{"uri":"a%2"}]}"#).unwrap_err();
        assert!(e.contains("image URI") && e.contains("cut short"), "{e}");
        assert!(
            refs("{\"buffers\": [")
                .unwrap_err()
                .contains("not glTF JSON")
        );
    }
}
