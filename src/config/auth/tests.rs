use super::*;

fn parse(text: &str) -> Result<Clients, AuthFileError> {
    Clients::parse(text, Path::new("auth.yaml"))
}

fn file_with(entries: &[String]) -> String {
    format!("clients:\n{}\n", entries.join("\n"))
}

#[test]
fn a_generated_entry_loads_and_identifies_its_token_only() {
    let robot = new_token();
    let ops = new_token();
    let text = file_with(&[
        entry_line("robot-7", &robot, [Scope::Pose].into_iter().collect()),
        entry_line(
            "ops.team_1",
            &ops,
            [Scope::Site, Scope::Admin, Scope::Metrics]
                .into_iter()
                .collect(),
        ),
    ]);
    let clients = parse(&text).expect("valid");
    assert_eq!(clients.len(), 2);
    let found = clients.identify(&robot).expect("robot's token");
    assert_eq!(found.name(), "robot-7");
    assert!(found.scopes().contains(Scope::Pose));
    assert!(!found.scopes().contains(Scope::Admin));
    assert_eq!(clients.identify(&ops).map(Client::name), Some("ops.team_1"));
    assert_eq!(clients.identify(&new_token()), None);
    assert_eq!(clients.identify(""), None);
    // A token differing in its last character is another token.
    let mut near = robot.clone();
    near.pop();
    near.push('x');
    assert_eq!(clients.identify(&near), None);
    assert_eq!(clients.file_sha256_hex().len(), 64);
}

#[test]
fn the_block_style_of_the_documentation_loads() {
    let text = format!(
        "clients:\n  - name: robot-7\n    token_sha256: \"{}\"\n    scopes: [pose]\n",
        token_sha256_hex("test")
    );
    let clients = parse(&text).expect("valid");
    assert_eq!(clients.identify("test").map(Client::name), Some("robot-7"));
    assert_eq!(
        token_sha256_hex("test"),
        "9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08"
    );
}

#[test]
fn an_empty_client_list_is_valid_and_locks_everything() {
    let clients = parse("clients: []\n").expect("valid");
    assert!(clients.is_empty());
    assert_eq!(clients.identify("anything"), None);
}

#[test]
fn refusals_name_the_line_and_the_reason() {
    let digest = token_sha256_hex("a");
    let other = token_sha256_hex("b");
    let cases: [(String, Option<usize>, &str); 8] = [
        (
            format!(
                "clients:\n  - name: -bad\n    token_sha256: \"{digest}\"\n    scopes: [pose]\n"
            ),
            Some(2),
            "starting with a letter or digit",
        ),
        (
            "clients:\n  - name: robot\n    token_sha256: \"abc\"\n    scopes: [pose]\n".to_owned(),
            Some(2),
            "64 hex digits",
        ),
        (
            format!(
                "clients:\n  - name: robot\n    token_sha256: \"{}\"\n    scopes: [pose]\n",
                "g".repeat(64)
            ),
            Some(2),
            "64 hex digits",
        ),
        (
            format!("clients:\n  - name: robot\n    token_sha256: \"{digest}\"\n    scopes: []\n"),
            Some(2),
            "no scope",
        ),
        (
            format!(
                "clients:\n  - name: robot\n    token_sha256: \"{digest}\"\n    scopes: [root]\n"
            ),
            Some(4),
            "unknown variant",
        ),
        (
            format!("clients:\n  - name: robot\n    token: \"{digest}\"\n    scopes: [pose]\n"),
            Some(3),
            "unknown field",
        ),
        (
            format!(
                "clients:\n  - {{name: a, token_sha256: \"{digest}\", scopes: [pose]}}\n  - {{name: a, token_sha256: \"{other}\", scopes: [pose]}}\n"
            ),
            Some(3),
            "given twice",
        ),
        (
            format!(
                "clients:\n  - {{name: a, token_sha256: \"{digest}\", scopes: [pose]}}\n  - {{name: b, token_sha256: \"{digest}\", scopes: [site]}}\n"
            ),
            Some(3),
            "has the token of \"a\"",
        ),
    ];
    for (text, line, reason) in cases {
        let err = parse(&text).expect_err(&text);
        assert_eq!(err.line, line, "{text}\n{err}");
        assert!(err.reason.contains(reason), "{text}\n{err}");
        assert!(err.to_string().starts_with("auth.yaml:"), "{err}");
    }
}

#[test]
fn a_missing_file_is_refused_with_its_name() {
    let err = Clients::load(Path::new("/nonexistent/auth.yaml")).expect_err("no file");
    assert!(
        err.to_string()
            .starts_with("/nonexistent/auth.yaml: cannot read"),
        "{err}"
    );
}

#[test]
fn tokens_are_fresh_prefixed_and_header_safe() {
    let a = new_token();
    let b = new_token();
    assert_ne!(a, b);
    assert_eq!(a.len(), TOKEN_PREFIX.len() + 43);
    assert!(a.starts_with(TOKEN_PREFIX));
    assert!(
        a.bytes()
            .all(|c| c.is_ascii_alphanumeric() || c == b'-' || c == b'_'),
        "{a}"
    );
}

#[test]
fn names_follow_the_label_rule() {
    for ok in ["robot-7", "a", "Ops.Team_1", &"x".repeat(MAX_NAME_LEN)] {
        assert!(check_name(ok).is_ok(), "{ok}");
    }
    for bad in [
        "",
        "-x",
        ".x",
        "has space",
        "é",
        "a/b",
        &"x".repeat(MAX_NAME_LEN + 1),
    ] {
        assert!(check_name(bad).is_err(), "{bad}");
    }
}

#[test]
fn scopes_print_as_in_the_file() {
    let scopes: Scopes = [Scope::Metrics, Scope::Pose].into_iter().collect();
    assert_eq!(scopes.to_string(), "pose, metrics");
    assert!(Scopes::default().is_empty());
}
