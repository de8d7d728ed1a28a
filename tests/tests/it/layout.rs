//! The workspace's shape, held by tests (ARCHITECTURE.md, issue 27):
//! dependencies flow one way between the crates, host-tools' modules import
//! each other without a cycle, no function outside tests is longer than
//! [`MAX_FUNCTION_LINES`], and the README's architecture map names every
//! crate of the workspace.
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// The workspace root (this crate lives in `tests/`).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// `cargo metadata` of the workspace, with the resolved dependency graph.
fn metadata() -> Value {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--locked"])
        .current_dir(root())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON")
}

/// The paper systems' crates: each may depend on `plant-common` only
/// (pushing also on `plant-contour`, whose splines score its contours).
const PAPER_CRATES: [&str; 7] = [
    "plant-viscoelastic",
    "plant-pushing",
    "plant-rheology",
    "plant-tetmsd",
    "plant-dlo",
    "plant-contour",
    "plant-tissue",
];

/// Workspace package name → the workspace packages it depends on (normal
/// dependencies; dev-dependencies are the tests' business), and the name of
/// every package (workspace or not) in its resolved normal-dependency
/// closure.
struct Graph {
    direct: BTreeMap<String, BTreeSet<String>>,
    closure: BTreeMap<String, BTreeSet<String>>,
}

fn graph(meta: &Value) -> Graph {
    let name_of: BTreeMap<&str, &str> = meta["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .map(|p| (p["id"].as_str().unwrap(), p["name"].as_str().unwrap()))
        .collect();
    let members: BTreeSet<&str> = meta["workspace_members"]
        .as_array()
        .expect("workspace_members")
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    // Normal (non-dev, non-build) edges of the resolved graph.
    let mut edges: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for node in meta["resolve"]["nodes"].as_array().expect("resolve") {
        let id = node["id"].as_str().unwrap();
        let deps = node["deps"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|d| {
                d["dep_kinds"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|k| k["kind"].is_null())
            })
            .map(|d| d["pkg"].as_str().unwrap())
            .collect();
        edges.insert(id, deps);
    }
    let mut direct = BTreeMap::new();
    let mut closure = BTreeMap::new();
    for &m in &members {
        let name = name_of[m].to_string();
        direct.insert(
            name.clone(),
            edges[m]
                .iter()
                .filter(|d| members.contains(*d))
                .map(|d| name_of[d].to_string())
                .collect(),
        );
        let mut seen = BTreeSet::new();
        let mut stack = edges[m].clone();
        while let Some(id) = stack.pop() {
            if seen.insert(name_of[id].to_string()) {
                stack.extend(edges.get(id).into_iter().flatten());
            }
        }
        closure.insert(name, seen);
    }
    Graph { direct, closure }
}

#[test]
fn dependencies_flow_one_way_between_the_crates() {
    let g = graph(&metadata());
    let deps = |name: &str| -> &BTreeSet<String> {
        g.direct
            .get(name)
            .unwrap_or_else(|| panic!("{name} is not a workspace member"))
    };
    assert!(
        deps("plant-common").is_empty(),
        "plant-common depends on {:?}",
        deps("plant-common")
    );
    for paper in PAPER_CRATES {
        let allowed: &[&str] = if paper == "plant-pushing" {
            &["plant-common", "plant-contour"]
        } else {
            &["plant-common"]
        };
        for d in deps(paper) {
            assert!(
                allowed.contains(&d.as_str()),
                "{paper} depends on {d}: a paper system depends on plant-common only"
            );
        }
    }
    for d in deps("plant-joint") {
        assert_eq!(d, "plant-common", "the joint depends on {d}");
    }
    for d in deps("hal-sim") {
        assert!(
            ["firmware", "plant-joint", "plant-common"].contains(&d.as_str()),
            "hal-sim depends on {d}: it needs the joint and the firmware core only"
        );
    }
    // The plant is the reference the firmware is tested against: no plant
    // crate may reach the firmware, directly or not.
    for (name, closure) in &g.closure {
        if name.starts_with("plant-") {
            assert!(
                !closure.contains("firmware"),
                "{name} reaches the firmware crate"
            );
        }
    }
}

#[test]
fn hal_sim_builds_without_any_paper_system_or_its_heavy_dependencies() {
    let g = graph(&metadata());
    let closure = &g.closure["hal-sim"];
    for banned in PAPER_CRATES
        .iter()
        .copied()
        .chain(["nifti", "ndarray", "robust", "crc"])
    {
        assert!(
            !closure.contains(banned),
            "hal-sim pulls in {banned} ({} packages in all)",
            closure.len()
        );
    }
    assert!(closure.contains("plant-joint"));
}

/// Every `.rs` file under `dir`, skipping `target/` and hidden folders.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if p.is_dir() {
            if name != "target" && !name.starts_with('.') {
                rust_files(&p, out);
            }
        } else if name.ends_with(".rs") {
            out.push(p);
        }
    }
}

/// `src` with comments, string and character literals blanked out (line
/// breaks kept), so braces and keywords inside them are not counted.
fn code_only(src: &str) -> String {
    let b = src.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let blank = |out: &mut Vec<u8>, s: &[u8]| {
        out.extend(s.iter().map(|&c| if c == b'\n' { b'\n' } else { b' ' }));
    };
    let mut i = 0;
    while i < b.len() {
        let rest = &b[i..];
        if rest.starts_with(b"//") {
            let end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
            blank(&mut out, &rest[..end]);
            i += end;
        } else if rest.starts_with(b"/*") {
            let (mut depth, mut j) = (0, 0);
            while j < rest.len() {
                if rest[j..].starts_with(b"/*") {
                    depth += 1;
                    j += 2;
                } else if rest[j..].starts_with(b"*/") {
                    depth -= 1;
                    j += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    j += 1;
                }
            }
            blank(&mut out, &rest[..j]);
            i += j;
        } else if let Some(len) = raw_string_len(b, i) {
            blank(&mut out, &b[i..i + len]);
            i += len;
        } else if rest[0] == b'"' {
            let mut j = 1;
            while j < rest.len() && rest[j] != b'"' {
                j += if rest[j] == b'\\' { 2 } else { 1 };
            }
            let end = (j + 1).min(rest.len());
            blank(&mut out, &rest[..end]);
            i += end;
        } else if let Some(len) = char_literal_len(rest) {
            blank(&mut out, &rest[..len]);
            i += len;
        } else {
            out.push(rest[0]);
            i += 1;
        }
    }
    String::from_utf8(out).expect("blanking keeps UTF-8 boundaries of ASCII code")
}

/// Length of a raw string literal (`r"…"`, `r#"…"#`, `br"…"`) starting at
/// `i`, if one does.
fn raw_string_len(b: &[u8], i: usize) -> Option<usize> {
    if i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_') {
        return None;
    }
    let mut j = i;
    if b.get(j) == Some(&b'b') {
        j += 1;
    }
    if b.get(j) != Some(&b'r') {
        return None;
    }
    j += 1;
    let hashes = b[j..].iter().take_while(|&&c| c == b'#').count();
    j += hashes;
    if b.get(j) != Some(&b'"') {
        return None;
    }
    j += 1;
    let mut close = vec![b'"'];
    close.extend(std::iter::repeat_n(b'#', hashes));
    let end = b[j..].windows(close.len()).position(|w| w == close)?;
    Some(j + end + close.len() - i)
}

/// Length of a character literal at the start of `rest` (`'a'`, `'\n'`,
/// `'\u{…}'`, `'é'`), or `None` for a lifetime or label.
fn char_literal_len(rest: &[u8]) -> Option<usize> {
    if rest.first() != Some(&b'\'') {
        return None;
    }
    if rest.get(1) == Some(&b'\\') {
        let end = rest[2..].iter().position(|&c| c == b'\'')?;
        return Some(end + 3);
    }
    // One UTF-8 character, then a quote.
    let first = *rest.get(1)?;
    let width = match first {
        0x00..=0x7f => 1,
        0xc0..=0xdf => 2,
        0xe0..=0xef => 3,
        _ => 4,
    };
    (rest.get(1 + width) == Some(&b'\'')).then_some(width + 2)
}

/// Every `fn` with a body in `code` (already [`code_only`]): its name, first
/// line and length in lines.
fn functions(code: &str) -> Vec<(String, usize, usize)> {
    let b = code.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(off) = code[i..].find("fn ") {
        let at = i + off;
        i = at + 3;
        if at > 0 && (b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_') {
            continue;
        }
        let name: String = code[i..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        if name.is_empty() {
            continue;
        }
        // The body's `{`, unless a `;` outside brackets ends the item first
        // (a declaration; the `;` of an array type `[T; N]` does not).
        let mut j = i;
        let mut open = None;
        let mut nesting = 0usize;
        while j < b.len() {
            match b[j] {
                b'(' | b'[' => nesting += 1,
                b')' | b']' => nesting = nesting.saturating_sub(1),
                b'{' if nesting == 0 => {
                    open = Some(j);
                    break;
                }
                b';' if nesting == 0 => break,
                _ => {}
            }
            j += 1;
        }
        let Some(open) = open else { continue };
        let mut depth = 0usize;
        let mut close = open;
        for (k, &c) in b.iter().enumerate().skip(open) {
            if c == b'{' {
                depth += 1;
            } else if c == b'}' {
                depth -= 1;
                if depth == 0 {
                    close = k;
                    break;
                }
            }
        }
        let first = code[..at].matches('\n').count() + 1;
        let last = code[..close].matches('\n').count() + 1;
        out.push((name, first, last - first + 1));
    }
    out
}

/// The longest a function outside tests may be (issue 27).
const MAX_FUNCTION_LINES: usize = 120;

#[test]
fn no_function_outside_tests_is_longer_than_the_limit() {
    let root = root();
    let mut files = Vec::new();
    for dir in [
        "firmware",
        "hal-sim",
        "plant-models",
        "host-tools",
        "tests/src",
    ] {
        rust_files(&root.join(dir), &mut files);
    }
    let mut long = Vec::new();
    for f in &files {
        let rel = f
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let in_test_tree = rel
            .split('/')
            .any(|c| matches!(c, "tests" | "benches" | "fuzz" | "examples"));
        if in_test_tree {
            continue;
        }
        let code = code_only(&std::fs::read_to_string(f).unwrap());
        // Unit tests sit in a `#[cfg(test)] mod …` at the end of a file.
        let tests_from = code
            .find("#[cfg(test)]\nmod ")
            .map(|at| code[..at].matches('\n').count() + 1)
            .unwrap_or(usize::MAX);
        for (name, line, len) in functions(&code) {
            if len > MAX_FUNCTION_LINES && line < tests_from {
                long.push(format!("{rel}:{line} fn {name}: {len} lines"));
            }
        }
    }
    assert!(
        files.len() > 100,
        "only {} source files found under {}",
        files.len(),
        root.display()
    );
    assert!(
        long.is_empty(),
        "functions longer than {MAX_FUNCTION_LINES} lines:\n{}",
        long.join("\n")
    );
}

#[test]
fn the_function_scanner_measures_what_it_should() {
    let src = "fn a() {\n    let s = \"}\";\n    let c = '}';\n    // }\n}\nfn b();\nfn c<T>(x: T) -> T where T: Copy {\n    x\n}\nfn d(v: [f64; 2]) -> [u8; 4] {\n    [0; 4]\n}\n";
    let f = functions(&code_only(src));
    assert_eq!(
        f,
        vec![
            ("a".to_string(), 1, 5),
            ("c".to_string(), 7, 3),
            ("d".to_string(), 10, 3)
        ],
        "{f:?}"
    );
}

/// Expands the path text after `crate::` (or `super::`) at the start of
/// `rest` into the module paths it names: `run::{sim::Row, trace}` gives
/// `run::sim::Row` and `run::trace`.
fn expand_path(rest: &str) -> Vec<String> {
    let ident = |s: &str| -> usize {
        s.char_indices()
            .find(|(_, c)| !(c.is_alphanumeric() || *c == '_' || *c == ':'))
            .map_or(s.len(), |(i, _)| i)
    };
    let head_len = ident(rest);
    let head = rest[..head_len].trim_end_matches(':');
    let after = &rest[head_len..];
    let Some(group) = after.strip_prefix('{') else {
        return vec![head.to_string()];
    };
    // The group up to its matching brace, split at top-level commas.
    let (mut depth, mut items, mut from) = (1, Vec::new(), 0);
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    items.push(&group[from..i]);
                    break;
                }
            }
            ',' if depth == 1 => {
                items.push(&group[from..i]);
                from = i + 1;
            }
            _ => {}
        }
    }
    items
        .into_iter()
        .map(str::trim)
        .filter(|i| !i.is_empty() && *i != "self")
        .flat_map(|i| expand_path(i).into_iter().map(|t| format!("{head}::{t}")))
        .chain(std::iter::once(head.to_string()))
        .map(|p| p.trim_start_matches("::").to_string())
        .collect()
}

/// The paths `code` imports through `crate::…`, and through `super::…`
/// (resolved against `parent`, the module that holds this file's module).
fn crate_imports(code: &str, parent: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for (kw, base) in [("crate::", ""), ("super::", parent)] {
        for (at, _) in code.match_indices(kw) {
            if at > 0 && code[..at].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == ':')
            {
                continue;
            }
            for p in expand_path(&code[at + kw.len()..]) {
                out.insert(if base.is_empty() {
                    p
                } else {
                    format!("{base}::{p}")
                });
            }
        }
    }
    out
}

#[test]
fn host_tools_modules_import_each_other_without_a_cycle() {
    let src = root().join("host-tools/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    // A file's module path: `run/sim.rs` is `run::sim`, `output/mod.rs` is
    // `output`. The binary's files (main.rs and commands/) import the
    // library as `host_tools::`, so they are a graph of their own; only the
    // library's modules are checked here, file by file.
    let module_of = |p: &Path| -> String {
        let rel = p.strip_prefix(&src).unwrap().with_extension("");
        let parts: Vec<String> = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .filter(|c| c != "mod")
            .collect();
        parts.join("::")
    };
    let mut code_of = BTreeMap::new();
    for f in &files {
        let m = module_of(f);
        if m == "main" || m == "lib" || m.starts_with("commands") {
            continue;
        }
        let code = code_only(&std::fs::read_to_string(f).unwrap());
        let code = match code.find("#[cfg(test)]\nmod ") {
            Some(at) => code[..at].to_string(),
            None => code,
        };
        code_of.insert(m, code);
    }
    let modules: BTreeSet<String> = code_of.keys().cloned().collect();
    // An imported path names the deepest module it starts with.
    let module_named = |path: &str| -> Option<String> {
        let segs: Vec<&str> = path.split("::").collect();
        (1..=segs.len())
            .rev()
            .map(|n| segs[..n].join("::"))
            .find(|p| modules.contains(p))
    };
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, code) in &code_of {
        // `super` of a file module is its folder's module; of a folder's
        // mod.rs, the folder above.
        let parent = m.rsplit_once("::").map_or("", |(p, _)| p);
        let targets = crate_imports(code, parent)
            .iter()
            .filter_map(|p| module_named(p))
            .filter(|t| t != m && !m.starts_with(&format!("{t}::")))
            .collect();
        edges.insert(m.clone(), targets);
    }
    assert!(modules.len() > 20, "host-tools modules: {modules:?}");
    // Depth-first search for a back edge.
    fn visit<'a>(
        m: &'a str,
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<&'a str, u8>,
        path: &mut Vec<&'a str>,
    ) -> Option<Vec<String>> {
        match state.get(m) {
            Some(2) => return None,
            Some(1) => {
                let from = path.iter().position(|p| *p == m).unwrap();
                let mut cycle: Vec<String> = path[from..].iter().map(|s| s.to_string()).collect();
                cycle.push(m.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(m, 1);
        path.push(m);
        for t in &edges[m] {
            if let Some(c) = visit(t, edges, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(m, 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in edges.keys() {
        if let Some(cycle) = visit(m, &edges, &mut state, &mut Vec::new()) {
            panic!(
                "host-tools modules import each other in a circle: {}",
                cycle.join(" → ")
            );
        }
    }
}

#[test]
fn imports_are_read_as_the_module_paths_they_name() {
    let code = "use crate::{sim, run::{trace::Row, report}};\nfn f() { crate::report::x(); super::y::z(); }";
    let got = crate_imports(&code_only(code), "run");
    let want: BTreeSet<String> = [
        "sim",
        "run",
        "run::trace::Row",
        "run::report",
        "report::x",
        "run::y::z",
        "",
    ]
    .map(String::from)
    .into();
    assert_eq!(got, want);
}

#[test]
fn the_readme_architecture_map_names_every_crate_and_nothing_that_is_gone() {
    let root = root();
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let start = readme
        .find("## Architecture")
        .expect("README has an Architecture section");
    let block_start = start + readme[start..].find("```").expect("a map in a code block") + 3;
    let block_end = block_start
        + readme[block_start..]
            .find("```")
            .expect("closed code block");
    let map = &readme[block_start..block_end];
    let meta = metadata();
    for p in meta["packages"].as_array().unwrap() {
        let manifest = PathBuf::from(p["manifest_path"].as_str().unwrap());
        let Ok(rel) = manifest.parent().unwrap().strip_prefix(&root) else {
            continue;
        };
        if !meta["workspace_members"]
            .as_array()
            .unwrap()
            .iter()
            .any(|m| m == &p["id"])
        {
            continue;
        }
        // The map draws folders as an indented tree: a member
        // `plant-models/joint` is the line `  joint/` under `plant-models/`.
        let leaf = format!("{}/", rel.file_name().unwrap().to_string_lossy());
        assert!(
            map.lines().any(|l| l.trim_start().starts_with(&leaf)),
            "the README's architecture map does not name {} ({leaf})",
            rel.display()
        );
    }
    // Every folder or file the map names at its top level exists.
    for line in map.lines() {
        let entry = line.split_whitespace().next().unwrap_or("");
        if !line.starts_with(' ') && (entry.ends_with('/') || entry.contains('.')) {
            assert!(
                root.join(entry).exists(),
                "the README's architecture map names {entry}, which does not exist"
            );
        }
    }
}
