"""docs/robots.md's examples run against the real service, so they stay true.

The page's commands talk to ``http://127.0.0.1:8765`` (a server without a token) and
``http://127.0.0.1:8766`` (one with ``SBPLAN_TOKEN``). The test starts both with ``sbplan serve``
on free ports of 127.0.0.1 once the page's ``calibrate`` step has written the calibration, and
runs every ``console`` block in order with those ports substituted (outputs compared as in
tests/test_docs.py: ``...`` stands for any text). A ``python`` block is a client that runs
alongside the commands that follow it; the next ``text`` block is what it must print.
"""

from __future__ import annotations

import doctest
import os
import re
import subprocess
import sys
import time
from pathlib import Path

from sbplan.bench.serve import Server
from test_docs import FLAGS, ROOT, blocks, console_steps

PAGE = ROOT / "docs" / "robots.md"
PORTS = {"8765": None, "8766": "a-token-for-the-docs-test-0123456789"}


def start(cwd: Path, env: dict, token: str | None) -> Server:
    env = dict(env)
    env.pop("SBPLAN_TOKEN", None)
    if token:
        env["SBPLAN_TOKEN"] = token
    return Server("calibration.json", cwd=cwd, env=env)


def test_robots_page_runs(tmp_path):
    text = PAGE.read_text(encoding="utf-8")
    (tmp_path / "maps").symlink_to(ROOT / "maps")
    env = {k: v for k, v in os.environ.items() if "proxy" not in k.lower()}  # 127.0.0.1 only, never a proxy
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["PYTHONPATH"] = os.pathsep.join(p for p in [str(ROOT), str(ROOT / "plugins"), env.get("PYTHONPATH", "")] if p)
    env["SBPLAN_TOKEN"] = PORTS["8766"]
    env["COLUMNS"] = "100"
    servers: dict[str, Server] = {}
    clients: list[tuple[subprocess.Popen, str, str]] = []
    checker = doctest.OutputChecker()
    found = [b for b in blocks(text) if b[0] in ("console", "python", "text")]

    def local(command: str) -> str:
        for port, token in PORTS.items():
            if f"127.0.0.1:{port}" in command:
                if port not in servers:
                    servers[port] = start(tmp_path, env, token)
                command = command.replace(f"127.0.0.1:{port}", f"127.0.0.1:{servers[port].port}")
        return command

    try:
        for i, (lang, body, line) in enumerate(found):
            where = f"robots.md:{line}"
            if lang == "console":
                for cmd, expected in console_steps(body):
                    out = subprocess.run(local(cmd), shell=True, cwd=tmp_path, env=env, capture_output=True,
                                         text=True, timeout=120)
                    got = out.stdout + out.stderr
                    assert checker.check_output(expected, got, FLAGS), f"{where}: `{cmd}` printed\n{got}\nexpected\n{expected}"
            elif lang == "python":
                script = tmp_path / f"client-{line}.py"
                script.write_text(local(body))
                server = next(iter(servers.values()))
                before = server.health()["clients"]
                proc = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True)
                deadline = time.monotonic() + 30
                while server.health()["clients"] == before:  # connected before the next command runs
                    assert proc.poll() is None and time.monotonic() < deadline, f"{where}: the client did not connect"
                    time.sleep(0.05)
                expected = next((b for lang2, b, _ in found[i + 1:] if lang2 == "text"), "")
                clients.append((proc, expected, where))
        for proc, expected, where in clients:
            got, _ = proc.communicate(timeout=60)
            assert proc.returncode == 0 and checker.check_output(expected, got, FLAGS), \
                f"{where}: the client printed\n{got}\nexpected\n{expected}"
        assert set(servers) == set(PORTS) and clients, "the page should use both servers and a client"
    finally:
        for proc, _, _ in clients:
            proc.kill()
        for server in servers.values():
            server.stop()


def test_robots_page_links_exist():
    for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", PAGE.read_text(encoding="utf-8")):
        assert (ROOT / "docs" / target).exists(), f"robots.md: broken link {target}"
