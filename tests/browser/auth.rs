//! The setup page against a service with an auth file (docs/security.md): a 401 asks for a
//! bearer token; a refused token asks again, saying so; the right one sends the request
//! again and every call after it, kept in the tab's sessionStorage only (no localStorage, no
//! cookie) and never printed in the curl command; cancelling the prompt shows the 401's
//! problem; and the browser's WebSocket to the stream passes with the token as the
//! `bearer.TOKEN` subprotocol (the `101` selecting `qrpose`) and fails without it.

use super::support::{Server, scratch_dir};
use super::webdriver::{Browser, ENTER};
use super::{DESKTOP, lock, open_page, photo, send_photo, wait_for_overlay};
use qrpose::config::auth::{Scope, entry_line, new_token};

/// The stream's query for the page's default camera.
const STREAM_QUERY: &str = "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50";

/// `qrpose serve --auth-file` with one client holding `pose` and `site`, and its token.
fn server_with_auth(name: &str) -> (Server, String) {
    let token = new_token();
    let file = scratch_dir("browser-auth").join(format!("{name}.yaml"));
    let entry = entry_line(
        "setup-laptop",
        &token,
        [Scope::Pose, Scope::Site].into_iter().collect(),
    );
    std::fs::write(&file, format!("clients:\n{entry}\n")).expect("an auth file");
    let server = Server::start_with(&["--auth-file", file.to_str().expect("UTF-8")]);
    (server, token)
}

/// Waits for the token prompt; its reason.
fn prompt_reason(browser: &Browser, containing: &str) -> String {
    let script = format!(
        "const p = document.getElementById('token-panel');
         const reason = document.getElementById('token-reason').textContent;
         return !p.hidden && reason.includes({containing:?}) && reason;"
    );
    browser
        .wait_for(&format!("the token prompt saying {containing:?}"), &script)
        .as_str()
        .expect("a reason")
        .to_owned()
}

/// Opens a WebSocket to the stream from the page, with `token` as a subprotocol when given;
/// `{state: "open", protocol}` or `{state: "closed", code}`.
fn stream_from_page(browser: &Browser, token: Option<&str>) -> serde_json::Value {
    browser.run(
        "const [query, token] = arguments;
         window.streamProbe = {state: 'opening'};
         const url = streamUrl(query);
         const socket = token ? new WebSocket(url, ['qrpose', 'bearer.' + token]) : new WebSocket(url);
         socket.onopen = () => { window.streamProbe = {state: 'open', protocol: socket.protocol}; socket.close(1000); };
         socket.onclose = (e) => { if (window.streamProbe.state === 'opening') window.streamProbe = {state: 'closed', code: e.code}; };
         return true;",
        &[STREAM_QUERY.into(), token.into()],
    );
    browser.wait_for(
        "the stream opened or closed",
        "return window.streamProbe.state !== 'opening' && window.streamProbe;",
    )
}

#[test]
fn a_401_asks_for_a_token_kept_by_the_tab_alone_and_the_request_goes_again_with_it() {
    let _one = lock();
    let (server, token) = server_with_auth("prompt");
    let (file, _) = photo();
    let browser = Browser::start(DESKTOP.0, DESKTOP.1);
    open_page(&browser, &server);

    send_photo(&browser, &file);
    let reason = prompt_reason(&browser, "asks for a bearer token");
    assert!(reason.contains("Authorization: Bearer"), "{reason}");
    assert_eq!(browser.focused_id(), "token-input");

    // A token no client holds: asked again.
    browser.type_into(
        &browser.find("#token-input"),
        "qrp_not-a-client-of-this-service",
    );
    browser.click(&browser.find("#token-use"));
    prompt_reason(&browser, "refused this tab's token");

    // The right one, by keyboard: the photo goes again and is answered.
    browser.type_into(&browser.find("#token-input"), &token);
    browser.press(ENTER);
    wait_for_overlay(&browser);
    let kept = browser.run(
        "return {session: sessionStorage.getItem('qrpose.token'), local: localStorage.length,
                 cookie: document.cookie, curl: document.getElementById('curl').textContent,
                 prompt_hidden: document.getElementById('token-panel').hidden,
                 error_hidden: document.getElementById('error').hidden};",
        &[],
    );
    assert_eq!(kept["session"], token.as_str(), "{kept}");
    assert_eq!(kept["local"], 0, "nothing in localStorage: {kept}");
    assert_eq!(kept["cookie"], "", "no cookie: {kept}");
    assert_eq!(kept["prompt_hidden"], true, "{kept}");
    assert_eq!(kept["error_hidden"], true, "{kept}");
    let curl = kept["curl"].as_str().expect("the curl command");
    assert!(
        curl.contains("-H \"Authorization: Bearer $QRPOSE_TOKEN\""),
        "{curl}"
    );
    assert!(!curl.contains(&token), "the token is not printed: {curl}");

    // Sent again without asking: the second request needs no prompt.
    browser.run("document.getElementById('status').textContent = '';", &[]);
    browser.click(&browser.find("#send"));
    browser.wait_for(
        "the second answer",
        "return document.getElementById('status').textContent.startsWith('Done');",
    );
    assert_eq!(
        browser.run("return document.getElementById('token-panel').hidden;", &[]),
        true
    );

    // The stream: the token as a subprotocol from the browser; refused without it.
    let with = stream_from_page(&browser, Some(&token));
    assert_eq!(with["state"], "open", "{with}");
    assert_eq!(with["protocol"], "qrpose", "{with}");
    let without = stream_from_page(&browser, None);
    assert_eq!(without["state"], "closed", "{without}");
}

#[test]
fn cancelling_the_token_prompt_shows_the_401_problem() {
    let _one = lock();
    let (server, _token) = server_with_auth("cancel");
    let (file, _) = photo();
    let browser = Browser::start(DESKTOP.0, DESKTOP.1);
    open_page(&browser, &server);

    send_photo(&browser, &file);
    prompt_reason(&browser, "asks for a bearer token");
    browser.click(&browser.find("#token-cancel"));
    let shown = browser.wait_for(
        "the error is shown",
        "const e = document.getElementById('error');
         return !e.hidden && {title: document.getElementById('error-title').textContent,
                              meta: document.getElementById('error-meta').textContent,
                              prompt_hidden: document.getElementById('token-panel').hidden};",
    );
    assert_eq!(shown["title"], "Unauthorized", "{shown}");
    let meta = shown["meta"].as_str().expect("meta");
    assert!(
        meta.contains("unauthorized") && meta.contains("401"),
        "{shown}"
    );
    assert_eq!(shown["prompt_hidden"], true, "{shown}");
}
