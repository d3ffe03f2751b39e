//! The browser viewer's files (`web/` at the repository root), embedded in the binary: the two
//! pages, their scripts and the vendored three.js (`web/vendor/three/SOURCE.md`).

/// `web/` from this file.
macro_rules! web {
    ($path:literal) => {
        include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/../../web/", $path))
    };
}

/// Every file served: path under `/static/` (or the page name), MIME type, bytes.
const FILES: &[(&str, &str, &[u8])] = &[
    ("index.html", HTML, web!("index.html")),
    ("view.html", HTML, web!("view.html")),
    ("index.js", JS, web!("index.js")),
    ("view.js", JS, web!("view.js")),
    ("wire.js", JS, web!("wire.js")),
    ("expressions.js", JS, web!("expressions.js")),
    ("heat.js", JS, web!("heat.js")),
    ("keys.js", JS, web!("keys.js")),
    ("style.css", "text/css; charset=utf-8", web!("style.css")),
    (
        "three/three.module.js",
        JS,
        web!("vendor/three/three.module.js"),
    ),
    (
        "three/three.core.js",
        JS,
        web!("vendor/three/three.core.js"),
    ),
    (
        "three/addons/loaders/GLTFLoader.js",
        JS,
        web!("vendor/three/addons/loaders/GLTFLoader.js"),
    ),
    (
        "three/addons/controls/OrbitControls.js",
        JS,
        web!("vendor/three/addons/controls/OrbitControls.js"),
    ),
    (
        "three/addons/utils/BufferGeometryUtils.js",
        JS,
        web!("vendor/three/addons/utils/BufferGeometryUtils.js"),
    ),
    (
        "three/addons/utils/SkeletonUtils.js",
        JS,
        web!("vendor/three/addons/utils/SkeletonUtils.js"),
    ),
    ("three/LICENSE", TEXT, web!("vendor/three/LICENSE")),
    ("three/SOURCE.md", TEXT, web!("vendor/three/SOURCE.md")),
];

const HTML: &str = "text/html; charset=utf-8";
const JS: &str = "text/javascript; charset=utf-8";
const TEXT: &str = "text/plain; charset=utf-8";

/// The embedded file at `path` (relative, as under `/static/`): its MIME type and bytes.
pub(super) fn asset(path: &str) -> Option<(&'static str, &'static [u8])> {
    FILES
        .iter()
        .find(|(p, _, _)| *p == path)
        .map(|(_, mime, bytes)| (*mime, *bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pages_and_three_js_are_embedded() {
        let (mime, page) = asset("view.html").unwrap();
        assert!(mime.starts_with("text/html"));
        let page = std::str::from_utf8(page).unwrap();
        // The import map points `three` at the embedded module, which imports the core by a
        // relative path that is embedded too.
        assert!(
            page.contains("\"three\": \"/static/three/three.module.js\""),
            "{page}"
        );
        let (_, module) = asset("three/three.module.js").unwrap();
        assert!(
            std::str::from_utf8(module)
                .unwrap()
                .contains("from './three.core.js'")
        );
        assert!(asset("three/three.core.js").is_some());
        assert!(asset("../Cargo.toml").is_none());
    }

    #[test]
    fn every_module_the_viewer_imports_is_embedded() {
        let (_, js) = asset("view.js").unwrap();
        let js = std::str::from_utf8(js).unwrap();
        let mut seen = 0;
        for line in js.lines().filter(|l| l.starts_with("import ")) {
            let Some(spec) = line.split('\'').nth(1) else {
                continue;
            };
            let path = if let Some(p) = spec.strip_prefix("/static/") {
                p.to_string()
            } else if let Some(p) = spec.strip_prefix("three/addons/") {
                format!("three/addons/{p}")
            } else {
                assert_eq!(spec, "three", "{line}");
                "three/three.module.js".to_string()
            };
            assert!(
                asset(&path).is_some(),
                "{path} (imported by view.js) is not embedded"
            );
            seen += 1;
        }
        // three, GLTFLoader, OrbitControls, wire, expressions, heat, keys.
        assert_eq!(seen, 7);
    }
}
