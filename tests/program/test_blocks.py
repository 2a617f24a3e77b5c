"""The block page (``parmor blocks DIR [--serve]``, issue 9) in a real browser: headless
Chromium (Debian's ``chromium``) driven by Playwright. A program is built by drag and drop,
its Python text checked against ``program.script.to_python``, run on the local server, and
the reply (verdict, path, animation) checked in the page; bad programs get errors in the
page while the server keeps serving; two clients at once; a run over the time limit.

Skips when chromium, Playwright or the npm files ('make web') are absent; fails under
CI=true. The README's screenshot (docs/blocks.png) is the hexapod's page after its run:
PARMOR_README_SHOT=FILE.png makes that test save it there too (then cropped and scaled).
"""

from __future__ import annotations

import contextlib
import http.client
import io
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from program.blocks import MAKE_TARGET, WEB_ENV, toolbox, web_dir
from synth.commands.cli import main
from tests.conftest import REPO, need
from tests.synth.verification.test_mobile_manipulator import KIF_DESIGNS, kif_args

#: Chromium's switches: headless, no network but the page's server, a software WebGL.
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--enable-unsafe-swiftshader",
]

#: The acceptance designs: name -> (parmor design arguments, the program built by drag
#: and drop: a behaviour inside a repeat (with its parameters), then another behaviour).
DESIGNS = {
    "hexapod": (
        ["rough-terrain-walking"],
        (("walking", {"steps": 1}), 2, ("turning", {"angle": 30})),  # degrees in the page
    ),
    "snake": (["sidewinding"], (("sidewinding", {"cycles": 2}), 2, ("rolling", {"cycles": 3}))),
    "cart": (["driving"], (("driving", {"seconds": 1.5}), 2, ("turning", {"angle": 90}))),
    "arm": (
        ["pick-and-place", "--param", "object_shape=cylinder"],
        (("positioning", {"z": 0.1}), 2, ("pick-and-place", {})),
    ),
    # KIF-only types
    "pentapod": (
        KIF_DESIGNS["pentapod"],
        (("walking", {"steps": 1}), 2, ("turning", {"angle": -30})),  # degrees in the page
    ),
    "mobile": (
        KIF_DESIGNS["mobile"],
        (("positioning", {"z": 0.05}), 2, ("travel", {"distance": 0.3})),
    ),
}


@pytest.fixture(scope="module")
def chromium():
    """A headless Chromium (Debian's, never a downloaded one), one for the module."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    need(exe is not None, "chromium is absent (apt-get install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        need(False, "the playwright Python package is absent (pip install -e '.[test]')")
    web = web_dir()
    need(
        (web / "node_modules" / "blockly").is_dir() and (web / "node_modules" / "three").is_dir(),
        f"the npm packages are absent ({MAKE_TARGET})",
    )
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


def _design(folder: Path, args: list[str]) -> Path:
    out, err = io.StringIO(), io.StringIO()
    code = main(["design", *args, "--no-input", "--no-verify", "--out", str(folder)], out, err)
    assert code == 0, err.getvalue()
    return folder


@pytest.fixture(scope="module")
def bundles(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("bundles")
    return {name: _design(root / name, kif_args(args, root)) for name, (args, _) in DESIGNS.items()}


class Server:
    """``parmor blocks DIR --serve --port 0`` as a child process (stopped with Ctrl-C)."""

    def __init__(self, bundle: Path, *extra: str) -> None:
        env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "synth.commands.cli",
                "blocks",
                str(bundle),
                "--serve",
                "--port",
                "0",
                *extra,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        line = self.proc.stdout.readline()
        if "http://" not in line:
            self.proc.kill()
            raise AssertionError(f"the server did not start: {line}{self.proc.stderr.read()}")
        self.url = line.split("http://", 1)[1].split()[0].rstrip("/")
        self.url = "http://" + self.url
        self.log: list[str] = []
        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self) -> None:
        for line in self.proc.stderr:
            self.log.append(line)

    def get(self, path: str) -> int:
        with urllib.request.urlopen(self.url + path, timeout=30) as r:
            return r.status

    def stop(self) -> int:
        """Ctrl-C; the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout=30)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()


@pytest.fixture(scope="module")
def servers(bundles):
    started: dict[str, Server] = {}

    def get(name: str, *extra: str) -> Server:
        key = " ".join([name, *extra])
        if key not in started:
            started[key] = Server(bundles[name], *extra)
        return started[key]

    yield get
    for s in started.values():
        s.stop()


def _open(chromium, url: str):
    page = chromium.new_page(viewport={"width": 1400, "height": 950})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    page.wait_for_function("window.parmor !== undefined")
    page.errors = errors
    return page


# --- drag and drop -------------------------------------------------------------------------

_FLYOUT_BLOCK = """async ([type]) => {
  await Blockly.renderManagement.finishQueuedRenders();
  const flyout = parmor.workspace.getToolbox().getFlyout();
  const block = flyout.getWorkspace().getTopBlocks(false).find((b) => b.type === type);
  const xy = block.getRelativeToSurfaceXY();
  const off = block.previousConnection.getOffsetInBlock();
  const c = Blockly.utils.svgMath.wsToScreenCoordinates(flyout.getWorkspace(),
    new Blockly.utils.Coordinate(xy.x + off.x, xy.y + off.y));
  const r = block.getSvgRoot().querySelector('.blocklyPath').getBoundingClientRect();
  return {x: r.left + 12, y: r.top + 12, cx: c.x, cy: c.y};
}"""

_SHOWS = """([type]) => {
  const flyout = parmor.workspace.getToolbox().getFlyout();
  return flyout.isVisible() &&
    flyout.getWorkspace().getTopBlocks(false).some((b) => b.type === type);
}"""

_DRAGGED = """async ([type, before]) => {
  await Blockly.renderManagement.finishQueuedRenders();
  const b = parmor.workspace.getAllBlocks(false).find(
    (b) => b.type === type && !before.includes(b.id));
  const xy = b.getRelativeToSurfaceXY();
  const off = b.previousConnection.getOffsetInBlock();
  const c = Blockly.utils.svgMath.wsToScreenCoordinates(parmor.workspace,
    new Blockly.utils.Coordinate(xy.x + off.x, xy.y + off.y));
  return {x: c.x, y: c.y};
}"""

_TARGET = """async ([id, input]) => {
  await Blockly.renderManagement.finishQueuedRenders();  // connections move when rendered
  const block = parmor.workspace.getBlockById(id);
  const conn = input ? block.getInput(input).connection : block.nextConnection;
  const xy = block.getRelativeToSurfaceXY();
  const off = conn.getOffsetInBlock();
  const c = Blockly.utils.svgMath.wsToScreenCoordinates(parmor.workspace,
    new Blockly.utils.Coordinate(xy.x + off.x, xy.y + off.y));
  return {x: c.x, y: c.y};
}"""


def drag(page, category: str, block_type: str, target_id: str, input_name: str | None) -> str:
    """Drag a ``block_type`` block from the toolbox's ``category`` onto the statement input
    ``input_name`` of block ``target_id`` (or under it: None); the new block's id."""
    before = set(page.evaluate("parmor.workspace.getAllBlocks(false).map((b) => b.id)"))
    row = page.locator(".blocklyToolboxCategory", has_text=category)
    for _ in range(2):  # a click on the open category closes it
        if page.evaluate(_SHOWS, [block_type]):
            break
        row.click()
    page.wait_for_function(_SHOWS, arg=[block_type])
    src = page.evaluate(_FLYOUT_BLOCK, [block_type])
    dst = page.evaluate(_TARGET, [target_id, input_name])
    # the block's connection follows the pointer at the grab's offset; come to the target
    # from below right, so that the preview of an earlier connection on the way (Blockly's
    # insertion marker) does not move the target away
    ex, ey = dst["x"] + src["x"] - src["cx"], dst["y"] + src["y"] - src["cy"]
    page.mouse.move(src["x"], src["y"])
    page.mouse.down()
    page.mouse.move(src["x"] + 5, src["y"] + 5)
    for k in range(1, 9):
        f = k / 8
        page.mouse.move(src["x"] + f * (ex + 80 - src["x"]), src["y"] + f * (ey + 160 - src["y"]))
    page.mouse.move(ex + 20, ey + 40)
    page.mouse.move(ex, ey)
    page.mouse.up()
    page.evaluate("Blockly.renderManagement.finishQueuedRenders()")
    after = page.evaluate("parmor.workspace.getAllBlocks(false).map((b) => [b.id, b.type])")
    new = [i for i, t in after if i not in before and t == block_type]
    assert len(new) == 1, f"dragging {block_type} made {len(new)} blocks"
    connected = page.evaluate(
        """([id, target, input]) => {
          const b = parmor.workspace.getBlockById(id);
          const t = parmor.workspace.getBlockById(target);
          return input ? t.getInputTargetBlock(input) === b : t.getNextBlock() === b;
        }""",
        [new[0], target_id, input_name],
    )
    where = page.evaluate(_DRAGGED, [block_type, sorted(before)])
    assert connected, (
        f"{block_type} did not snap into {input_name or 'next'}: its connection is at "
        f"{where}, the target at {dst}; grabbed at {src}"
    )
    return new[0]


def set_fields(page, block_id: str, values: dict) -> None:
    page.evaluate(
        """([id, values]) => {
          const b = parmor.workspace.getBlockById(id);
          for (const [k, v] of Object.entries(values)) b.setFieldValue(v, k);
        }""",
        [block_id, values],
    )


def build(page, program) -> None:
    """Drag ``(behaviour A, params), times, (behaviour B, params)`` into the program:
    repeat(times) { A } then B."""
    (a, pa), times, (b, pb) = program
    start = page.evaluate("parmor.workspace.getTopBlocks(false)[0].id")
    rep = drag(page, "Control", "parmor_repeat", start, "BODY")
    set_fields(page, rep, {"TIMES": times})
    inner = drag(page, "Behaviours", f"parmor_do:{a}", rep, "BODY")
    set_fields(page, inner, pa)
    after = drag(page, "Behaviours", f"parmor_do:{b}", rep, None)
    set_fields(page, after, pb)


#: the page shows the Python text of its blocks (Blockly reports changes asynchronously)
_PYTHON_SHOWN = "document.getElementById('python').textContent === parmor.python()"


def run_in_page(page, body: str | None = None) -> dict:
    """Press Run (or post ``body`` through the page) and wait for the reply in the page."""
    runs = page.evaluate("parmor.state.runs")
    if body is None:
        page.click("#run")
    else:
        page.evaluate("(b) => { parmor.run(b); }", body)
    page.wait_for_function(f"parmor.state.runs > {runs}", timeout=300_000)
    return page.evaluate(
        "({error: parmor.state.error, status: document.getElementById('status').textContent})"
    )


# --- tests ---------------------------------------------------------------------------------


def test_two_hexapods_of_different_sizes_get_identical_toolboxes(bundles, tmp_path) -> None:
    from program.blocks import bundle_controller, read_record

    small = bundles["hexapod"]
    large = _design(tmp_path / "large", [*DESIGNS["hexapod"][0], "--param", "obstacle_height=6cm"])
    recs = [read_record(f) for f in (small, large)]
    assert recs[0]["lengths_m"] != recs[1]["lengths_m"]
    boxes = [
        toolbox(bundle_controller(f, r), r["abilities"])
        for f, r in zip((small, large), recs, strict=True)
    ]

    # the same blocks; their defaults and ranges are each design's own (issue 24)
    def blocks(box: list[dict]) -> list:
        own = ("default", "low", "high")
        return [
            {**b, "params": [{k: v for k, v in p.items() if k not in own} for p in b["params"]]}
            for b in box
        ]

    assert blocks(boxes[0]) == blocks(boxes[1])
    assert boxes[0] != boxes[1]
    assert {b["name"] for b in boxes[0]} >= {"walking", "turning"}
    # every parameter is shown with its unit and limits
    for b in boxes[0]:
        for p in b["params"]:
            assert p["kind"] == "choice" and p["choices"] or p["low"] is not None, p


def test_blocks_needs_the_npm_files_and_a_bundle(tmp_path, monkeypatch, bundles) -> None:
    monkeypatch.setenv(WEB_ENV, str(tmp_path / "nowhere"))
    out, err = io.StringIO(), io.StringIO()
    assert main(["blocks", str(bundles["cart"])], out, err) == 2
    assert MAKE_TARGET in err.getvalue() and "Traceback" not in err.getvalue()
    monkeypatch.delenv(WEB_ENV)
    err = io.StringIO()
    assert main(["blocks", str(tmp_path)], out, err) == 2
    assert "no design.json" in err.getvalue()
    err = io.StringIO()
    assert main(["blocks", str(bundles["cart"]), "--port", "9"], out, err) == 2
    assert "--serve" in err.getvalue()


def test_page_offline_shows_the_python_of_the_blocks(chromium, bundles) -> None:
    from program.script import number_text, to_python

    out, err = io.StringIO(), io.StringIO()
    assert main(["blocks", str(bundles["hexapod"])], out, err) == 0, err.getvalue()
    page = _open(chromium, (bundles["hexapod"] / "blocks" / "index.html").as_uri())
    try:
        assert page.is_disabled("#run")
        # a program with every kind of block and awkward numbers, loaded as Blockly JSON
        page.evaluate(
            """() => {
              const ws = parmor.workspace;
              const start = ws.getTopBlocks(false)[0];
              const mk = (type, fields) => {
                const b = ws.newBlock(type); b.initSvg(); b.render();
                for (const [k, v] of Object.entries(fields || {})) b.setFieldValue(v, k);
                return b;
              };
              const walk = mk('parmor_do:walking', {steps: 2, speed: 0.03, stride: 1e-5});
              const rep = mk('parmor_repeat', {TIMES: 3});
              rep.getInput('BODY').connection.connect(walk.previousConnection);
              const cond = mk('parmor_if', {REPORT: 'heading_deg', OP: '>=', VALUE: 45.5});
              const wait = mk('parmor_wait', {SECONDS: 0.25});
              cond.getInput('THEN').connection.connect(wait.previousConnection);
              const turn = mk('parmor_do:turning', {angle: -1.5, gait: 'wave'});
              start.getInput('BODY').connection.connect(rep.previousConnection);
              rep.nextConnection.connect(cond.previousConnection);
              cond.nextConnection.connect(turn.previousConnection);
            }"""
        )
        program = page.evaluate("parmor.programJson()")
        page.wait_for_function(_PYTHON_SHOWN)
        text = page.inner_text("#python")
        assert text == page.evaluate("parmor.python()")
        assert text == to_python(program)
        assert program["program"][0]["repeat"] == 3
        assert program["program"][1]["else"] == []
        assert "robot.wait(0.25)" in text and "stride=1e-05" in text
        # Python's repr of floats, whatever JavaScript's String() says
        for x in (0.1, 1e-5, 2.5e-7, 1e16, -3.0, -0.0, 123456.789, 1e21, 1e22, 5e-324, 1 / 3):
            assert page.evaluate(f"parmor.pyNumber({x!r})") == number_text(x), x
        assert not page.errors
    finally:
        page.close()


@pytest.mark.parametrize("name", list(DESIGNS))
def test_drag_and_drop_program_runs_end_to_end(chromium, servers, name, tmp_path) -> None:
    from program.script import to_python

    server = servers(name)
    page = _open(chromium, server.url + "/")
    try:
        assert page.is_enabled("#run")
        build(page, DESIGNS[name][1])
        program = page.evaluate("parmor.programJson()")
        (a, pa), times, (b, pb) = DESIGNS[name][1]
        assert [s.get("do") or "repeat" for s in program["program"]] == ["repeat", b]
        assert program["program"][0]["repeat"] == times
        assert program["program"][0]["body"][0]["do"] == a
        page.wait_for_function(_PYTHON_SHOWN)
        assert page.inner_text("#python") == to_python(program)
        reply = run_in_page(page)
        assert reply["error"] is None, reply
        result = page.evaluate("parmor.state.reply")
        ran = [s.get("behavior") or s.get("behaviour") for s in result["steps"]]
        assert ran == [a] * times + [b]
        # the robot ends where the program says: every behaviour within its verdict criteria
        assert result["verdict"] == "ok", [s["verdict"] for s in result["steps"]]
        assert all(s["verdict"] == "ok" for s in result["steps"])
        assert page.inner_text("#verdict-overall") == "ok"
        if result["final_pose"] is None:  # a fixed base
            assert page.is_visible("#no-path")
        else:
            n = int(page.get_attribute("#travelled", "data-points"))
            assert n == len(result["path"]["x"]) > 1
            # the robot ends where the program says (the session's end-pose criterion)
            assert result["end_pose_error_m"] is not None
        assert page.locator("#steps tr").count() == times + 2
        page.wait_for_function("parmor.animation.frame >= 0 || parmor.animation.error")
        assert page.evaluate("parmor.animation.error") is None
        assert page.evaluate("parmor.animation.geoms") == len(result["animation"]["geoms"])
        page.screenshot(path=str(tmp_path / f"{name}.png"))
        if name == "hexapod" and os.environ.get("PARMOR_README_SHOT"):
            page.screenshot(path=os.environ["PARMOR_README_SHOT"])
        assert not page.errors
    finally:
        page.close()


def test_bad_programs_get_errors_in_the_page_and_the_server_keeps_serving(
    chromium, servers
) -> None:
    server = servers("cart")
    page = _open(chromium, server.url + "/")
    try:
        cases = {
            "malformed": ('{"program": [', "not JSON"),
            "oversized": (json.dumps({"program": [{"wait": 1}] * 20000}), "too large"),
            "unknown behaviour": (json.dumps({"program": [{"do": "flying"}]}), "flying"),
            "not a program": ("[1, 2]", "program"),
            "NaN": ('{"program": [{"wait": NaN}]}', "NaN (not a number JSON allows)"),
        }
        for case, (body, expected) in cases.items():
            reply = run_in_page(page, body)
            assert reply["error"] and expected in reply["error"], (case, reply)
            assert reply["status"].startswith("error:"), case
            assert server.get("/blocks/index.html") == 200
        # a value beyond its limits, typed into a block
        start = page.evaluate("parmor.workspace.getTopBlocks(false)[0].id")
        block = drag(page, "Behaviours", "parmor_do:driving", start, "BODY")
        set_fields(page, block, {"v": 99})
        page.wait_for_function(_PYTHON_SHOWN)
        warned = page.evaluate(
            "(id) => parmor.workspace.getBlockById(id).hasIcon(Blockly.icons.IconType.WARNING)",
            block,
        )
        assert warned  # the page marks the field before the server refuses it
        # Run refuses it in the page: nothing is sent
        reply = run_in_page(page)
        assert reply["error"].startswith("not sent: driving: v 99 is outside"), reply
        # and the server refuses it too when it is sent anyway
        program = page.evaluate("JSON.stringify(parmor.programJson())")
        reply = run_in_page(page, program)
        assert reply["error"].startswith("program[0].params.v"), reply
        assert "99" in reply["error"]
        assert server.proc.poll() is None
    finally:
        page.close()


def test_two_clients_at_once(chromium, servers) -> None:
    server = servers("cart")
    program = json.dumps({"program": [{"do": "driving", "params": {"seconds": 1.0}}]})
    pages = [_open(chromium, server.url + "/") for _ in range(2)]
    try:
        for p in pages:
            p.evaluate("(b) => { parmor.run(b); }", program)
        for p in pages:
            p.wait_for_function("parmor.state.runs > 0", timeout=300_000)
            assert p.evaluate("parmor.state.error") is None
            assert p.evaluate("parmor.state.reply.steps.length") == 1
    finally:
        for p in pages:
            p.close()


def test_a_program_over_the_time_limit_is_stopped(chromium, servers) -> None:
    # 280 simulated seconds (within the program limit of 300) cannot run in 0.3 s of wall
    # time: MuJoCo steps a cart at a few hundred times real time at most
    server = servers("cart", "--time-limit", "0.3")
    page = _open(chromium, server.url + "/")
    try:
        body = [{"do": "driving", "params": {"seconds": 20}}]
        long = {"program": [{"repeat": 14, "body": body}]}
        reply = run_in_page(page, json.dumps(long))
        assert "time limit of 0.3 s" in (reply["error"] or ""), reply
        assert server.get("/blocks/index.html") == 200
    finally:
        page.close()
    assert server.stop() == 0  # Ctrl-C stops it cleanly
    assert any("stopped serving" in line for line in server.log)
    assert not any("Traceback" in line for line in server.log), "\n".join(server.log)


def test_the_server_listens_on_loopback_only_and_refuses_other_sites(servers) -> None:
    server = servers("cart")
    assert server.url.startswith("http://127.0.0.1:")
    port = int(server.url.rsplit(":", 1)[1])
    assert server.get("/blocks/index.html") == 200
    for headers in ({"Host": f"evil.example:{port}"}, {"Origin": "http://evil.example"}):
        req = urllib.request.Request(
            server.url + "/run", data=b'{"program": []}', headers=headers, method="POST"
        )
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(req, timeout=30)
        assert e.value.code == 403
    # the bundle's other files are not served, nor anything outside it
    for path in ("/design.json", "/blocks/../design.json", "/meshes/../../etc/passwd"):
        with pytest.raises(urllib.error.HTTPError) as e:
            server.get(path)
        assert e.value.code == 404


def test_a_run_waits_for_a_free_slot_within_its_time_limit(bundles) -> None:
    from http import HTTPStatus

    from program.server import RunFailed, Runner

    runner = Runner(bundles["cart"], time_limit=0.2, max_runs=1)
    assert runner.slots.acquire(timeout=1)  # another run holds the only slot
    with pytest.raises(RunFailed) as e:
        runner.run({"program": [{"wait": 1}]})
    assert e.value.status == HTTPStatus.SERVICE_UNAVAILABLE and "busy" in str(e.value)


def test_a_design_with_sensing_gets_its_sensing_blocks(bundles) -> None:
    """The toolbox offers what a program may call (program_behaviors): the sensing
    behaviours too, and nothing for a sensing ability the design does not have."""
    from program.blocks import bundle_controller, read_record, toolbox

    rec = read_record(bundles["cart"])
    c = bundle_controller(bundles["cart"], rec)
    plain = [b["name"] for b in toolbox(c, rec["abilities"])]
    sensing = [b["name"] for b in toolbox(c, [*rec["abilities"], "line-tracking"])]
    assert "line-tracking" not in plain and sensing == sorted([*plain, "line-tracking"])


_PROBE = """
import os, sys
started = []
sys.addaudithook(lambda event, args: started.append(args) if event == "subprocess.Popen" else None)
if sys.argv[1] == "cli":
    from synth.commands.cli import main
    main(["blocks", "--help"], open(os.devnull, "w"), open(os.devnull, "w"))
import mujoco
print(len(started))
"""


def test_the_command_line_imports_mujoco_without_a_child_process() -> None:
    # `import mujoco` on Linux runs a Python child to probe glfw unless MUJOCO_GL says
    # otherwise; a run killed at its time limit left that child printing a BrokenPipeError
    # traceback into the server's log. The command line turns the probe off for its process
    # and those it starts; without it (the built-to-fail case) the child is started.
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["PYTHONPATH"] = str(REPO)

    def children(how: str) -> int:
        r = subprocess.run(
            [sys.executable, "-c", _PROBE, how],
            capture_output=True,
            text=True,
            env=env,
            cwd=REPO,
            timeout=120,
        )
        assert r.returncode == 0, r.stderr
        return int(r.stdout)

    assert children("cli") == 0
    if sys.platform.startswith("linux"):
        assert children("bare") >= 1


# --- the server's bounds, in-process (no browser) --------------------------------------------


@contextlib.contextmanager
def serving(bundle: Path, **options):
    """A BlocksServer on a free port in a thread of this process; its log in ``.log``."""
    from program.server import BlocksServer

    log = io.StringIO()
    server = BlocksServer(bundle, 0, log=log, **options)
    server.log_text = log
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=60)


def post(server, body: bytes, timeout: float = 300) -> tuple[int, dict]:
    """POST /run with ``body``: (status, the JSON reply)."""
    port = server.server_address[1]
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        conn.request("POST", "/run", body=body, headers={"Content-Type": "application/json"})
        r = conn.getresponse()
        return r.status, json.loads(r.read())
    finally:
        conn.close()


def page_status(server) -> int:
    port = server.server_address[1]
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    try:
        conn.request("GET", "/blocks/index.html")
        r = conn.getresponse()
        r.read()  # closing on an unread reply resets the connection
        return r.status
    finally:
        conn.close()


@pytest.fixture(scope="module")
def cart_page(bundles) -> Path:
    """The cart's bundle with its block page written (``parmor blocks``)."""
    from program.blocks import write_page

    need(web_dir() is not None, f"the npm files are absent ({MAKE_TARGET})")
    write_page(bundles["cart"])
    return bundles["cart"]


def test_every_bad_body_is_answered_4xx_with_a_message(cart_page) -> None:
    """Cases built to fail: a 30,000-deep body got no reply at all; huge integers were 500;
    wrong types were tracebacks in the server's log."""
    bodies = {
        "deep": (b"[" * 30_000 + b"]" * 30_000, 400, "nested deeper than 64"),
        "deep object": (b'{"a":' * 10_000 + b"1" + b"}" * 10_000, 400, "line 1 column 321"),
        "5000 digits": (
            b'{"program": [{"wait": %s}]}' % (b"9" * 5000),
            422,
            "program[0].wait = an integer of 5000 digits (too large): not a number",
        ),
        "400 digits": (
            b'{"program": [{"do": "driving", "params": {"seconds": %s}}]}' % (b"1" * 400),
            422,
            "program[0].params.seconds = an integer of 400 digits (too large): not a number",
        ),
        "1e400": (b'{"program": [{"wait": 1e400}]}', 422, "program[0].wait = "),
        "report list": (
            b'{"program": [{"if": {"report": ["x_m"], "op": ">", "value": 1}}]}',
            422,
            "program[0].if.report = ['x_m']: not one of",
        ),
        "op object": (
            b'{"program": [{"if": {"report": "x_m", "op": {}, "value": 1}}]}',
            422,
            "program[0].if.op = ",
        ),
        "params list": (
            b'{"program": [{"do": "driving", "params": {"seconds": [1]}}]}',
            422,
            "program[0].params.seconds = [1]: not a number",
        ),
        "not UTF-8": (b'{"program": ["\xe9"]}', 400, "not UTF-8"),
        "cut short": (b'{"program": [', 400, "the program is not JSON: line 1 column 14"),
    }
    with serving(cart_page) as server:
        for case, (body, status, message) in bodies.items():
            got, reply = post(server, body)
            assert (got, case) == (status, case) and message in reply["error"], (case, reply)
            assert page_status(server) == 200, case
        log = server.log_text.getvalue()
    assert "Traceback" not in log and "failed" not in log, log


def _read_all(s: socket.socket) -> bytes:
    data = b""
    while chunk := s.recv(4096):
        data += chunk
    return data


def test_connections_are_capped(cart_page) -> None:
    """A case built to fail: 30 idle connections held 30 threads; now 4 are served (a
    thread each) and the others answered 503 at once and closed. Checked through the
    server's counters (``BlocksServer.wait_until``), never against a clock: it passes on a
    machine running other jobs."""
    with serving(cart_page, max_connections=4) as server:
        address = ("127.0.0.1", server.server_address[1])
        idle = [socket.create_connection(address, timeout=600) for _ in range(4)]
        assert server.wait_until(lambda s: s.serving_now == 4, timeout=600)
        refused = [socket.create_connection(address, timeout=600) for _ in range(26)]
        for s in refused:
            head, _, body = _read_all(s).partition(b"\r\n\r\n")
            s.close()
            assert head.startswith(b"HTTP/1.1 503"), head
            assert "4 connections open" in json.loads(body)["error"]
        assert server.wait_until(lambda s: s.refused == 26, timeout=600)
        assert server.serving_now == 4  # the idle ones, a thread each
        for s in idle:
            s.close()
        # their threads see the end and free their slots
        assert server.wait_until(lambda s: s.serving_now == 0, timeout=600)
        assert page_status(server) == 200
        log = server.log_text.getvalue()
    assert "Traceback" not in log, log


def test_a_request_trickled_line_by_line_is_cut_at_the_request_time_limit(cart_page) -> None:
    """A case built to fail: a client that sent a header line now and then held its
    connection for as long as it went on (the silence timeout was per line). The whole
    request must now arrive within ``request_timeout``; the client here would take 120 s."""
    with serving(cart_page, request_timeout=0.5, socket_timeout=60) as server:
        address = ("127.0.0.1", server.server_address[1])
        with socket.create_connection(address, timeout=600) as slow:
            slow.sendall(b"GET /blocks/index.html HTTP/1.1\r\n")
            closed = False
            for i in range(600):
                try:
                    slow.sendall(b"X-Slow-%d: %d\r\n" % (i, i))
                except OSError:
                    closed = True
                    break
                if server.timed_out:
                    break
                time.sleep(0.2)
            assert closed or server.wait_until(lambda s: s.timed_out >= 1, timeout=600)
        assert server.wait_until(lambda s: s.serving_now == 0, timeout=600)
        assert page_status(server) == 200
        log = server.log_text.getvalue()
    assert "Traceback" not in log, log


def test_idle_and_slow_connections_time_out(cart_page) -> None:
    """Cases built to fail: a connection that sends nothing was kept open for ever; one
    whose body stops coming is answered 408 after the socket timeout (1 s here)."""
    with serving(cart_page, socket_timeout=1.0) as server:
        address = ("127.0.0.1", server.server_address[1])
        with socket.create_connection(address, timeout=120) as idle:
            assert idle.recv(4096) == b""  # closed by the server (before the 120 s here)
        with socket.create_connection(address, timeout=120) as slow:
            slow.sendall(
                b'POST /run HTTP/1.1\r\nHost: %s:%d\r\nContent-Length: 100\r\n\r\n{"pro'
                % (address[0].encode(), address[1])
            )
            reply = _read_all(slow)
        assert reply.startswith(b"HTTP/1.1 408"), reply
        assert b"did not arrive within 1 s" in reply
        assert page_status(server) == 200
        log = server.log_text.getvalue()
    assert "Traceback" not in log, log


def test_runs_at_once_are_capped_by_memory_and_cpus(cart_page, monkeypatch) -> None:
    """Cases built to fail: 8 CPUs with memory for two runs give two slots, not eight."""
    from program import server as srv

    per = srv.RUN_MEMORY_MB
    assert srv.run_slots(8, 2.5 * per) == 2
    assert srv.run_slots(8, 0.5 * per) == 1  # one run is always allowed
    assert srv.run_slots(2, 100 * per) == 2
    assert srv.run_slots(3, None) == 3  # memory unknown: the CPUs
    if sys.platform.startswith("linux"):
        assert srv.available_memory_mb() > 0
    monkeypatch.setattr(srv, "available_memory_mb", lambda: 1.5 * per)
    monkeypatch.setattr(srv.os, "cpu_count", lambda: 16)
    with serving(cart_page) as server:
        assert server.runner.max_runs == 1


_MEASURE = """
import json, resource, sys
from pathlib import Path
from program.server import Runner

if __name__ == "__main__":
    runner = Runner(Path(sys.argv[1]), time_limit=3000, max_runs=1)
    reply = runner.run(json.loads(sys.argv[2]))
    seconds = json.loads(reply)["result"]["seconds"]
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # KB -> MB
    print(json.dumps({"seconds": seconds, "child_mb": peak, "reply_mb": len(reply) / 2**20}))
"""


def test_a_run_of_the_longest_program_fits_the_memory_estimate(bundles, tmp_path) -> None:
    """RUN_MEMORY_MB against a measurement: the longest program a run may simulate (300 s)
    on the hexapod (the most drawn parts): its process's peak and its reply."""
    from program.server import RUN_MEMORY_MB

    script = tmp_path / "measure.py"
    script.write_text(_MEASURE)
    program = {"program": [{"repeat": 5, "body": [{"wait": 59.5}]}]}
    r = subprocess.run(
        [sys.executable, str(script), str(bundles["hexapod"]), json.dumps(program)],
        capture_output=True,
        text=True,
        timeout=1800,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
    )
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads(r.stdout)
    assert m["seconds"] > 290
    assert m["child_mb"] + 2 * m["reply_mb"] < RUN_MEMORY_MB, m


@pytest.mark.parametrize("limit", ["1e10", "86401", "0.01", "0", "-1", "nan", "inf"])
def test_time_limits_the_server_cannot_honour_are_refused_at_start(
    bundles, tmp_path, limit: str
) -> None:
    """A case built to fail: --time-limit 1e10 was accepted and every run failed with 500."""
    from adron.errors import InputError
    from program.server import TIME_LIMIT_RANGE, Runner

    folder = tmp_path / "cart"
    shutil.copytree(bundles["cart"], folder, ignore=shutil.ignore_patterns("blocks"))
    out, err = io.StringIO(), io.StringIO()
    code = main(["blocks", str(folder), "--serve", "--time-limit", limit], out, err)
    low, high = TIME_LIMIT_RANGE
    assert code == 2 and f"expected seconds in [{low:g}, {high:g}]" in err.getvalue()
    assert "Traceback" not in err.getvalue()
    assert not (folder / "blocks").exists()  # refused before anything is written
    with pytest.raises(InputError):
        Runner(folder, float(limit), 1)
