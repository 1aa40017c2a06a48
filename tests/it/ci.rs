//! The CI recipes pass a workflow linter, and the linter catches broken
//! ones. The linter is check-jsonschema (PyPI), which carries GitHub's and
//! GitLab's workflow schemas; `scripts/setup.sh --validation` installs it
//! and exports LANCER_CHECK_JSONSCHEMA. No registry reachable from CI ships
//! rhysd's actionlint itself (see docs/ci.md).
//!
//! - `.github/workflows/lancer.yml` passes GitHub's workflow schema, the
//!   rule that every job has a timeout, and `tests/ci/workflow-requirements.json`
//!   (what the job must do: cache, test, render the gallery, upload);
//! - the GitLab recipe in `docs/ci.md` passes GitLab's schema;
//! - each of a list of broken copies fails, with the linter naming the fault.

use crate::common;
use common::repo;

use std::path::{Path, PathBuf};
use std::process::Command;

/// The check-jsonschema to run: `$LANCER_CHECK_JSONSCHEMA`, else where
/// `scripts/setup.sh` installs it, else the one on PATH.
fn linter() -> PathBuf {
    if let Ok(path) = std::env::var("LANCER_CHECK_JSONSCHEMA") {
        return PathBuf::from(path);
    }
    let home = std::env::var("HOME").unwrap_or_default();
    let installed = Path::new(&home).join(".cache/lancer/tools/bin/check-jsonschema");
    if installed.is_file() {
        return installed;
    }
    PathBuf::from("check-jsonschema")
}

/// What the linter says about `file` against one schema.
#[derive(Clone, Copy)]
enum Schema {
    /// One of check-jsonschema's built-in schemas.
    Builtin(&'static str),
    /// lancer's own requirements on its workflow.
    Requirements,
}

/// Runs the linter on `file`; returns whether it passed and what it printed.
fn lint(file: &Path, schema: Schema) -> (bool, String) {
    let mut cmd = Command::new(linter());
    match schema {
        Schema::Builtin(name) => cmd.args(["--builtin-schema", name]),
        Schema::Requirements => cmd
            .arg("--schemafile")
            .arg(repo("tests/ci/workflow-requirements.json")),
    };
    let out = cmd.arg(file).output().unwrap_or_else(|e| {
        panic!(
            "cannot run {} ({e}); scripts/setup.sh --validation installs it",
            linter().display()
        )
    });
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// Every check the GitHub workflow must pass.
const GITHUB_CHECKS: [Schema; 3] = [
    Schema::Builtin("vendor.github-workflows"),
    Schema::Builtin("custom.github-workflows-require-timeout"),
    Schema::Requirements,
];

const WORKFLOW: &str = ".github/workflows/lancer.yml";

#[test]
fn github_workflow_passes_the_linter() {
    for schema in GITHUB_CHECKS {
        let (ok, text) = lint(&repo(WORKFLOW), schema);
        assert!(ok && text.contains("ok -- validation done"), "{text}");
    }
}

/// `text` with `from` replaced by `to`, which must occur in it.
fn broken(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "the recipe no longer holds {from:?}");
    text.replacen(from, to, 1)
}

#[test]
fn the_linter_catches_broken_github_workflows() {
    let good = std::fs::read_to_string(repo(WORKFLOW)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // (what is broken, from, to, the check that must fail, what it says)
    let cases: [(&str, &str, &str, Schema, &str); 9] = [
        (
            "no runs-on",
            "    runs-on: ubuntu-latest\n",
            "",
            GITHUB_CHECKS[0],
            "'runs-on' is a required property",
        ),
        (
            "a misspelt key",
            "    steps:\n",
            "    step:\n",
            GITHUB_CHECKS[0],
            "'step' was unexpected",
        ),
        (
            "a timeout that is not a number",
            "timeout-minutes: 90",
            "timeout-minutes: ninety",
            GITHUB_CHECKS[0],
            "'ninety' is not of type 'number'",
        ),
        (
            "a step with both uses and run",
            "      - uses: actions/checkout@v4\n",
            "      - uses: actions/checkout@v4\n        run: echo both\n",
            GITHUB_CHECKS[0],
            "is not valid under any of the given schemas",
        ),
        (
            "a YAML syntax error",
            "    defaults:\n",
            "    defaults: [\n",
            GITHUB_CHECKS[0],
            "Failed to parse",
        ),
        (
            "no timeout",
            "    timeout-minutes: 90\n",
            "",
            GITHUB_CHECKS[1],
            "'timeout-minutes' is a required property",
        ),
        (
            "no cache",
            "uses: actions/cache@v4",
            "uses: actions/checkout@v4",
            GITHUB_CHECKS[2],
            "are valid under the given schema",
        ),
        (
            "no stats from the gallery",
            "--stats-json",
            "--trace",
            GITHUB_CHECKS[2],
            "are valid under the given schema",
        ),
        (
            "no test run",
            "scripts/test.sh 2>&1",
            "cargo test 2>&1",
            GITHUB_CHECKS[2],
            "are valid under the given schema",
        ),
    ];
    for (i, (what, from, to, schema, says)) in cases.into_iter().enumerate() {
        let path = dir.path().join(format!("broken-{i}.yml"));
        std::fs::write(&path, broken(&good, from, to)).unwrap();
        let (ok, text) = lint(&path, schema);
        assert!(!ok, "{what}: the linter passed it");
        assert!(text.contains(says), "{what}: expected {says:?} in\n{text}");
    }
}

/// The `yaml` block after the `<!-- gitlab-ci` marker in docs/ci.md.
fn gitlab_recipe() -> String {
    let doc = std::fs::read_to_string(repo("docs/ci.md")).unwrap();
    let after = doc
        .split_once("<!-- gitlab-ci")
        .expect("docs/ci.md has the gitlab-ci marker")
        .1;
    let block = after.split_once("```yaml\n").expect("a yaml block").1;
    block
        .split_once("```\n")
        .expect("the block ends")
        .0
        .to_string()
}

#[test]
fn gitlab_recipe_passes_the_linter_and_a_broken_one_fails() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join(".gitlab-ci.yml");
    let recipe = gitlab_recipe();
    std::fs::write(&good, &recipe).unwrap();
    let (ok, text) = lint(&good, Schema::Builtin("vendor.gitlab-ci"));
    assert!(ok, "{text}");
    for (from, to, says) in [
        (
            "  stage: gallery\n",
            "  stage: gallery\n  scrpt: []\n",
            "'scrpt' was unexpected",
        ),
        (
            "timeout: 90 minutes",
            "timeout: [90]",
            "is not of type 'string'",
        ),
    ] {
        let bad = dir.path().join("broken.yml");
        std::fs::write(&bad, broken(&recipe, from, to)).unwrap();
        let (ok, text) = lint(&bad, Schema::Builtin("vendor.gitlab-ci"));
        assert!(!ok && text.contains(says), "{from:?} -> {to:?}:\n{text}");
    }
    // Both recipes render the same gallery the same way
    let github = std::fs::read_to_string(repo(WORKFLOW)).unwrap();
    for line in [
        "--var-out \"artifacts/gallery/$name.var.exr\"",
        "scripts/test.sh 2>&1 | tee artifacts/test.log",
    ] {
        assert!(recipe.contains(line) && github.contains(line), "{line}");
    }
}
