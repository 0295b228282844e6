"""Who may see the monitor and who may operate a run from it: checked on the server, never trusted to the page."""

import socket
import urllib.error
import urllib.request

import pytest
from journals import make_journal

from rdea_lab.monitor.access import Access, Controls, NotController, check_bind, websocket_origins
from rdea_lab.runs.control import REQUESTS, RunControl
from rdea_lab.specs import SpecError

pytest.importorskip("bokeh", reason="the monitor's page needs bokeh (pip install 'rdea-lab[monitor]')")

TOKEN = "a-viewing-token-0123456789"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_roles_from_the_request_arguments():
    access = Access(secret="s3cret-s3cret")
    assert access.role({}) == "viewer"
    assert access.role({"control": [b"wrong"]}) == "viewer"
    assert access.role({"control": [b"s3cret-s3cret"]}) == "controller"
    guarded = Access(TOKEN, secret="s3cret-s3cret")
    assert guarded.role({"control": [b"s3cret-s3cret"]}) == "refused"  # the secret is no token
    assert guarded.role({"token": [TOKEN.encode()], "control": ["s3cret-s3cret"]}) == "controller"
    view, control = guarded.urls("127.0.0.1", 5006)
    assert view == f"http://127.0.0.1:5006/?token={TOKEN}" and control == view + "&control=s3cret-s3cret"
    assert len(Access().secret) >= 32  # secrets.token_urlsafe(24)


@pytest.fixture
def journal(tmp_path):
    j = make_journal(tmp_path / "run.nc.part")
    RunControl().attach(j)  # what the engine does for every run: its requests folder
    return j


def test_a_session_without_the_secret_cannot_act(journal):
    controls = Controls(Access(secret="s3cret-s3cret"), wait=0)
    try:
        for given in (None, "", "s3cret", "s3cret-s3creT"):
            with pytest.raises(NotController, match="control URL"):
                controls.press(given, journal, "abort")
        assert not list((journal / REQUESTS).iterdir())
        state = controls.press("s3cret-s3cret", journal, "pause", "look").result(timeout=10)
        assert state == {}  # wait=0: sent, not waited for
        (sent,) = (journal / REQUESTS).iterdir()
        assert '"action": "pause"' in sent.read_text() and '"by": "monitor"' in sent.read_text()
    finally:
        controls.close()


def test_the_page_handler_rechecks_the_secret(journal, tmp_path):
    """A viewer's page whose buttons were enabled by hand (the page is not trusted) still writes nothing."""
    from bokeh.document import Document

    from rdea_lab.monitor.app import LiveView
    from rdea_lab.monitor.hub import Hub

    access = Access(secret="s3cret-s3cret")
    controls, hub = Controls(access, wait=0), Hub(tmp_path)
    try:
        hub.update(force=True)
        view = LiveView(Document(), hub, controls, {}, "viewer")
        assert view.key == str(journal) and all(b.disabled for b in view.buttons.values())
        view.buttons["pause"].disabled = False
        view.press("pause")
        assert "refused" in view.message.text and not list((journal / REQUESTS).iterdir())
        boss = LiveView(Document(), hub, controls, {"control": [b"s3cret-s3cret"]}, "controller")
        assert not any(b.disabled for b in boss.buttons.values())
        boss.press("pause")
        assert "sent" in boss.message.text
    finally:
        controls.close()
        hub.close()


def test_a_non_loopback_bind_needs_a_token(tmp_path):
    with pytest.raises(SpecError, match="not a loopback address"):
        check_bind("0.0.0.0", None)
    check_bind("127.0.0.1", None)
    check_bind("0.0.0.0", TOKEN)
    from rdea_lab.monitor import Monitor

    with pytest.raises(SpecError, match="bind: 192.0.2.1 is not a loopback address"):
        Monitor(tmp_path, bind="192.0.2.1")
    assert websocket_origins("127.0.0.1", 5006) == ["127.0.0.1:5006", "localhost:5006"]
    assert f"{socket.gethostname()}:80" in websocket_origins("0.0.0.0", 80)


def test_sessions_without_the_token_are_refused(tmp_path):
    from bokeh.document import Document

    from rdea_lab.monitor import Monitor
    from rdea_lab.monitor.app import make_document

    port = free_port()
    with Monitor(tmp_path, port=port, token=TOKEN) as mon:
        for query in ("", "?token=wrong-token-0123456789"):
            with pytest.raises(urllib.error.HTTPError) as refused:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/{query}", timeout=20)
            # an HTTPError holds its response's connection open: closed here, not by a garbage collection
            # in some later test (CI's nested suite failed on that "unclosed socket" in a physics test)
            refused.value.close()
            assert refused.value.code == 403
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/?token={TOKEN}", timeout=20) as page:
            assert page.status == 200 and b"bokeh" in page.read().lower()
        doc = Document()  # a session made without the page (no request arguments): nothing in it
        assert make_document(doc, mon.hub, mon.access, mon.controls) is None
        assert len(doc.roots) == 1 and "refused" in doc.roots[0].text and not doc.callbacks.session_callbacks


def test_text_from_a_journal_is_shown_never_run(tmp_path):
    """Whoever can write a journal below DIR must not get markup (a script) into the controller's page."""
    from bokeh.document import Document

    from rdea_lab.monitor.app import LiveView
    from rdea_lab.monitor.hub import Hub

    make_journal(tmp_path / "x.nc.part", attrs={"protocol_name": "<img src=x onerror=alert(1)>"})
    hub = Hub(tmp_path)
    try:
        hub.update(force=True)
        view = LiveView(Document(), hub, Controls(Access(), wait=0), {}, "viewer")
        view._show_state(hub.feeds[view.key])
        assert "<img" not in view.state.text and "&lt;img" in view.state.text
    finally:
        hub.close()


def test_the_control_url_is_kept_for_its_user_only(tmp_path, monkeypatch):
    import stat

    from rdea_lab.monitor.server import _keep_control_url

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    kept = _keep_control_url("http://127.0.0.1:5006/?control=s3cret", 5006)
    assert kept == tmp_path / "rdea-lab" / "monitor-5006.url"
    assert kept.read_text() == "http://127.0.0.1:5006/?control=s3cret\n"
    assert stat.S_IMODE(kept.stat().st_mode) == 0o600 and stat.S_IMODE(kept.parent.stat().st_mode) == 0o700
