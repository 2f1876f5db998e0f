"""The editor end to end in headless Chromium: the page shows the mesh, a GC changed through the
page reaches the server and comes back as a new mesh, a bad value is refused on the page, and
the program saved from the page replays with edit.py to the same mesh."""
import time

import pytest
import yaml

from tests.app.editor import browser
from ngc_gen.app.editor.server import EditorServer
from ngc_gen.app.editor.start import open_session

from .conftest import RES, editor_config, mesh_chamfer
from .test_session import replay

pytestmark = pytest.mark.usefixtures("single_thread")


@pytest.fixture
def server(checkpoint, tmp_path):
    cfg = editor_config(checkpoint, "shape=one", f"editor.port={browser.free_port()}",
                        "editor.preview_resolution=24", f"editor.refine_resolution={RES}",
                        "editor.refine_delay_s=0.2", "editor.environment=null",
                        f"editor.out_dir={tmp_path / 'editor'}")
    session, latent = open_session(cfg)
    srv = EditorServer(session, cfg.editor, latent, out_dir=tmp_path / "editor")
    yield srv
    srv.stop()


def test_edit_in_the_browser_then_replay(server, checkpoint, tmp_path):
    if not browser.CHROMIUM.exists():
        pytest.skip(f"{browser.CHROMIUM} is missing and could not be installed here (needs "
                    "root or sudo for `apt-get install -y chromium`; `make setup` does it)")
    playwright = pytest.importorskip("playwright.sync_api")
    t0 = time.perf_counter()
    with playwright.sync_playwright() as p:
        chrome = browser.launch(p)
        try:
            page = chrome.new_page(viewport=browser.VIEWPORT)
            browser.open_editor(page, server.url, RES)
            before = server.shown_mesh().mesh

            # a bad value through the page: refused, the shape stays at version 0
            browser.set_number(page, "radius", 0)
            browser.wait_for_message(page, r"^refused: .*factor = 0.*must be positive")
            assert server.session.version == 0 and server.session.ops == []

            # a GC changed through the page: the server answers with a new mesh
            browser.set_number(page, "twist (deg)", 90)
            status = browser.wait_for_mesh(page, 1, RES)
            assert server.session.ops == [{"op": "twist", "gc": "body", "t": 0.0,
                                           "degrees": 90.0}]
            after = server.shown_mesh().mesh  # what the page shows
            assert f"{len(after.faces)} faces" in status
            assert mesh_chamfer(before, after) > 1e-6  # the mesh did change

            browser.click(page, "save program")
            saved = browser.wait_for_message(page, r"^saved ")
            page.screenshot(path=str(tmp_path / "editor.png"))
        finally:
            chrome.close()
    program = tmp_path / "editor" / "program.yaml"
    assert saved == f"saved {program}"
    assert yaml.safe_load(program.read_text())["ops"][0]["degrees"] == 90.0
    assert (tmp_path / "editor.png").stat().st_size > 10_000
    theirs = replay(tmp_path, checkpoint, program)
    assert mesh_chamfer(after, theirs) < 1e-8
    print(f"browser round trip {time.perf_counter() - t0:.1f} s")
