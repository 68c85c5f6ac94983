"""A robot computer's install: ``pip install parkfleet[robot]`` into a fresh virtual
environment has no server or bench packages, and ``parkfleet agent --drive sim`` runs.

Slow (a virtual environment and a download of the robot's packages: about a minute with a
warm pip cache): marked ``slow``, it runs with the rest (CI included); ``-m "not slow"``
leaves it out of an inner loop.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from support import wait_for

from fleet.core.wire import Keys
from fleet.io.settings import load_settings
from fleet.io.transport import listening_locators, open_session, tcp_endpoint

pytestmark = [pytest.mark.integration, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
#: What a robot must not carry (the server's and the benchmarks' packages).
SERVER_PACKAGES = ("fastapi", "uvicorn", "scipy", "matplotlib", "navground", "httpx")
#: Copied to build from: the package and its metadata, none of the checkout's build debris.
_NOT_SOURCE = shutil.ignore_patterns(
    ".*", "build", "*.egg-info", "__pycache__", "var", "artifacts", "tests", "docs", "*.png"
)


def _clean_env() -> dict[str, str]:
    """This environment without what points Python at the checkout or the shared venv."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


@pytest.fixture(scope="module")
def robot_venv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with ``parkfleet[robot]`` installed from a copy of this checkout."""
    tmp = tmp_path_factory.mktemp("robot-install")
    source = tmp / "parkfleet"
    shutil.copytree(ROOT, source, ignore=_NOT_SOURCE)
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, env=_clean_env())
    subprocess.run(
        [str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet", f"{source}[robot]"],
        check=True,
        env=_clean_env(),
        cwd=tmp,
    )
    return venv


def test_a_robot_install_has_no_server_or_bench_packages(robot_venv: Path) -> None:
    probe = (
        "import importlib.util, sys; "
        f"print(' '.join(m for m in {SERVER_PACKAGES!r} if importlib.util.find_spec(m)))"
    )
    found = subprocess.run(
        [str(robot_venv / "bin" / "python"), "-c", probe],
        check=True,
        capture_output=True,
        text=True,
        env=_clean_env(),
        cwd=robot_venv,
    ).stdout.split()
    assert found == []
    # the ROS 2 drive's package is there; the command says what a server command needs
    served = subprocess.run(
        [str(robot_venv / "bin" / "parkfleet"), "serve"],
        capture_output=True,
        text=True,
        env=_clean_env(),
        cwd=robot_venv,
    )
    assert served.returncode == 2 and "parkfleet[server]" in served.stderr, served.stderr


def test_the_agent_of_a_robot_install_drives_a_sim_robot_against_a_router(
    robot_venv: Path,
) -> None:
    settings = load_settings(listen=["tcp/127.0.0.1:0"])
    keys = Keys(settings.fleet_name)
    seen = threading.Event()
    with open_session(settings, "router") as router:
        endpoint = tcp_endpoint(listening_locators(router))
        sub = router.declare_subscriber(keys.state("r1"), lambda _sample: seen.set())
        agent = subprocess.Popen(
            [
                str(robot_venv / "bin" / "parkfleet"),
                "agent",
                "--id",
                "r1",
                "--drive",
                "sim",
                "--connect",
                endpoint,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=_clean_env(),
            cwd=robot_venv,
        )
        try:
            wait_for(lambda: seen.is_set() or agent.poll() is not None, 60, "the agent's state")
            assert agent.poll() is None, agent.communicate()[1]
        finally:
            agent.send_signal(signal.SIGTERM)
            out, err = agent.communicate()
            sub.undeclare()
    assert agent.returncode == 0, err
    assert "agent r1 running" in out
