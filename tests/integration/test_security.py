"""Security on real Zenoh: usrpwd, mutual TLS and the fleet access-control list.

Certificates are generated at test time (a throw-away CA, a router certificate for
127.0.0.1, client certificates whose common name is the identity, and a rogue CA).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
from support import wait_for

from fleet.cli.main import main as parkfleet_main
from fleet.core.params import Gains, Tolerance
from fleet.core.wire import Keys, ParkAssignment, Pose, RobotState, encode
from fleet.io.decoder import Decoder
from fleet.io.settings import Settings, load_settings
from fleet.io.transport import listening_locators, open_session

pytestmark = pytest.mark.integration

KEYS = Keys()
PARKFLEET = Path(sys.executable).with_name("parkfleet")
CLI = [str(PARKFLEET)] if PARKFLEET.exists() else [sys.executable, "-m", "fleet.cli"]
PASSWORDS = {"fleet": "fleet-pw", "ops": "ops-pw", "r1": "r1-pw", "r2": "r2-pw"}


# -- certificates ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Pki:
    folder: Path

    @property
    def ca(self) -> Path:
        return self.folder / "ca.pem"

    def cert(self, name: str) -> Path:
        return self.folder / f"{name}.pem"

    def key(self, name: str) -> Path:
        return self.folder / f"{name}.key"


Key = ec.EllipticCurvePrivateKey


def _name(common_name: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])


def _write(
    folder: Path, name: str, cert: x509.Certificate, key: ec.EllipticCurvePrivateKey
) -> None:
    (folder / f"{name}.pem").write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    (folder / f"{name}.key").write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )


def _builder(subject: x509.Name, issuer: x509.Name, key: Key) -> x509.CertificateBuilder:
    now = dt.datetime.now(dt.UTC)
    return (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(issuer)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=1))
    )


def _ca(common_name: str) -> tuple[x509.Certificate, Key]:
    key = ec.generate_private_key(ec.SECP256R1())
    usage = x509.KeyUsage(
        digital_signature=True, content_commitment=False, key_encipherment=False,
        data_encipherment=False, key_agreement=False, key_cert_sign=True, crl_sign=True,
        encipher_only=False, decipher_only=False,
    )  # fmt: skip
    cert = (
        _builder(_name(common_name), _name(common_name), key)
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .add_extension(usage, critical=True)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return cert, key


def _leaf(common_name: str, ca: tuple[x509.Certificate, Key]) -> tuple[x509.Certificate, Key]:
    """A certificate for ``common_name``, valid for localhost / 127.0.0.1, server and client."""
    ca_cert, ca_key = ca
    key = ec.generate_private_key(ec.SECP256R1())
    names = [x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
    usage = [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
    cert = (
        _builder(_name(common_name), ca_cert.subject, key)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.SubjectAlternativeName(names), critical=False)
        .add_extension(x509.ExtendedKeyUsage(usage), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False
        )
        .sign(ca_key, hashes.SHA256())
    )
    return cert, key


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    """A CA with certificates for two routers, the fleet service, an operator and robots r1,
    r2; and a certificate for "r1" signed by a rogue CA."""
    folder = tmp_path_factory.mktemp("pki")
    ca = _ca("parkfleet test CA")
    _write(folder, "ca", *ca)
    for name in ("router", "site-b", "fleet", "ops", "r1", "r2"):
        _write(folder, name, *_leaf(name, ca))
    _write(folder, "rogue-r1", *_leaf("r1", _ca("rogue CA")))
    return Pki(folder)


# -- helpers --------------------------------------------------------------------------------
@pytest.fixture
def credentials(tmp_path: Path) -> Path:
    path = tmp_path / "users.txt"
    path.write_text("".join(f"{user}:{pw}\n" for user, pw in PASSWORDS.items()))
    return path


@contextmanager
def running_router(settings: Settings) -> Iterator[tuple[Any, str]]:
    """A router session with its real endpoint (the ``:0`` port resolved)."""
    scheme = settings.listen[0].split("/")[0] + "/"
    with open_session(settings, "router") as session:
        endpoint = next(loc for loc in listening_locators(session) if loc.startswith(scheme))
        yield session, endpoint


class Collector:
    """Every (key, payload) a subscriber receives."""

    def __init__(self, session: Any, key_expr: str) -> None:
        self.lock = threading.Lock()
        self.samples: list[tuple[str, bytes]] = []
        self.sub = session.declare_subscriber(key_expr, self._on)

    def _on(self, sample: Any) -> None:
        with self.lock:
            self.samples.append((str(sample.key_expr), sample.payload.to_bytes()))

    def seen(self) -> set[tuple[str, bytes]]:
        with self.lock:
            return set(self.samples)


def put_until(
    session: Any, key: str, payload: bytes, done: Callable[[], bool], timeout: float = 10.0
) -> None:
    """Re-send (subscriptions take a moment to propagate) until ``done``."""

    def sent() -> bool:
        if done():
            return True
        session.put(key, payload)
        return False

    wait_for(sent, timeout, f"{key} to arrive", poll=0.05)


def alive_tokens(session: Any) -> set[str]:
    return {
        str(reply.ok.key_expr)
        for reply in session.liveliness().get(KEYS.all_alive, timeout=2.0)
        if reply.ok is not None
    }


# -- authentication -------------------------------------------------------------------------
def test_wrong_or_missing_password_cannot_connect(credentials: Path) -> None:
    router_settings = load_settings(listen=["tcp/127.0.0.1:0"], zenoh_credentials_file=credentials)
    with running_router(router_settings) as (router, endpoint):
        for user, password in (("r1", "wrong"), ("intruder", "r1-pw"), (None, None)):
            settings = load_settings(connect=[endpoint], zenoh_user=user, zenoh_password=password)
            with pytest.raises(ConnectionError), open_session(settings, "client"):
                pass
        inbox = Collector(router, "parkfleet/test/**")
        good = load_settings(connect=[endpoint], zenoh_user="r1", zenoh_password="r1-pw")
        with open_session(good, "client") as session:
            put_until(session, "parkfleet/test/hello", b"hi", lambda: bool(inbox.seen()))
        inbox.sub.undeclare()
    assert inbox.seen() == {("parkfleet/test/hello", b"hi")}


def test_client_without_a_certificate_of_the_fleet_ca_cannot_connect(pki: Pki) -> None:
    router_settings = load_settings(
        listen=["tls/127.0.0.1:0"], tls_root_ca=pki.ca,
        tls_cert=pki.cert("router"), tls_key=pki.key("router"),
    )  # fmt: skip
    with running_router(router_settings) as (router, endpoint):
        refused = [
            load_settings(connect=[endpoint], tls_root_ca=pki.ca),  # no client certificate
            load_settings(  # a certificate from another CA
                connect=[endpoint],
                tls_root_ca=pki.ca,
                tls_cert=pki.cert("rogue-r1"),
                tls_key=pki.key("rogue-r1"),
            ),
            load_settings(connect=[endpoint.replace("tls/", "tcp/")]),  # plain TCP to TLS
        ]
        for settings in refused:
            with pytest.raises(ConnectionError), open_session(settings, "client"):
                pass
        inbox = Collector(router, "parkfleet/test/**")
        good = load_settings(
            connect=[endpoint], tls_root_ca=pki.ca, tls_cert=pki.cert("r1"), tls_key=pki.key("r1")
        )
        with open_session(good, "client") as session:
            put_until(session, "parkfleet/test/hello", b"hi", lambda: bool(inbox.seen()))
        inbox.sub.undeclare()
    assert inbox.seen() == {("parkfleet/test/hello", b"hi")}


# -- access control -------------------------------------------------------------------------
def _acl_settings(
    identity: str, pki: Pki, credentials: Path
) -> tuple[Settings, Callable[..., Settings]]:
    """Router settings with the generated ACL, and a factory of client settings."""
    if identity == "username":  # usrpwd over TCP
        router = load_settings(
            listen=["tcp/127.0.0.1:0"], zenoh_credentials_file=credentials, acl=True,
            acl_operator_users=["ops"],
        )  # fmt: skip

        def client(endpoint: str, who: str) -> Settings:
            return load_settings(connect=[endpoint], zenoh_user=who, zenoh_password=PASSWORDS[who])

        return router, client
    router = load_settings(
        listen=["tls/127.0.0.1:0"], tls_root_ca=pki.ca,
        tls_cert=pki.cert("router"), tls_key=pki.key("router"),
        acl=True, acl_identity="cert_common_name", acl_robot_ids=["r1", "r2"],
        acl_operator_users=["ops"],
    )  # fmt: skip

    def tls_client(endpoint: str, who: str) -> Settings:
        return load_settings(
            connect=[endpoint], tls_root_ca=pki.ca, tls_cert=pki.cert(who), tls_key=pki.key(who)
        )

    return router, tls_client


@pytest.mark.parametrize("identity", ["username", "cert_common_name"])
def test_robot_cannot_publish_another_robots_keys_or_send_assignments(
    identity: str, pki: Pki, credentials: Path
) -> None:
    router_settings, client = _acl_settings(identity, pki, credentials)
    with (
        running_router(router_settings) as (router, endpoint),
        open_session(client(endpoint, "r1"), "client") as r1,
        open_session(client(endpoint, "r2"), "client") as r2,
        open_session(client(endpoint, "fleet"), "client") as fleet,
    ):
        at_router = Collector(router, "parkfleet/**")  # local: sees all the router routes
        at_service = Collector(fleet, KEYS.all_states)
        r2_orders = Collector(r2, KEYS.assignment("r2"))
        r1_snoops = Collector(r1, KEYS.assignment("r2"))  # eavesdropping is refused too
        own_token = r1.liveliness().declare_token(KEYS.alive("r1"))
        forged_token = r1.liveliness().declare_token(KEYS.alive("r2"))
        own_state = (KEYS.state("r1"), b"own")
        order = (KEYS.assignment("r2"), b"from-fleet")

        def forge_and_send() -> None:
            r1.put(KEYS.state("r2"), b"forged-state")
            r1.put(KEYS.assignment("r2"), b"forged-assignment")
            r1.put(KEYS.assignment("r1"), b"self-assignment")
            r1.put(*own_state)
            fleet.put(*order)

        # Forged puts go first on the same links: once the allowed ones arrived, any forged
        # put that the router let through would have arrived before them.
        def allowed_arrived() -> bool:
            if (
                own_state in at_router.seen()
                and own_state in at_service.seen()
                and order in r2_orders.seen()
            ):
                return True
            forge_and_send()
            return False

        wait_for(allowed_arrived, 10.0, "the allowed messages", poll=0.05)
        for _ in range(5):
            forge_and_send()
        # Fences after the last forged puts: r1's own state on r1's link; once the router
        # (and the service) saw it, the router had judged every forged put before it. Then
        # the fleet's on the router's link to r2: it comes after anything let through.
        fences = ((KEYS.state("r1"), b"fence"), (KEYS.assignment("r2"), b"fence"))
        r1.put(*fences[0])
        wait_for(
            lambda: fences[0] in at_router.seen() and fences[0] in at_service.seen(),
            10.0, "r1's fence",
        )  # fmt: skip
        fleet.put(*fences[1])
        wait_for(
            lambda: fences[1] in r2_orders.seen() and fences[1] in at_router.seen(),
            10.0, "the fleet's fence",
        )  # fmt: skip
        wait_for(lambda: KEYS.alive("r1") in alive_tokens(router), 5.0, "r1's token")
        tokens = alive_tokens(router)
        own_token.undeclare()
        forged_token.undeclare()
        for collector in (at_router, at_service, r2_orders, r1_snoops):
            collector.sub.undeclare()

    assert at_router.seen() == {own_state, order, *fences}
    assert at_service.seen() == {own_state, fences[0]}
    assert r2_orders.seen() == {order, fences[1]}
    assert order not in r1_snoops.seen()  # (r1's own forged puts loop back in its session)
    assert tokens == {KEYS.alive("r1")}


def test_meshed_routers_each_enforce_the_acl_for_their_own_robots(pki: Pki) -> None:
    """Fleet host router A and site router B (``--connect`` A), mutual TLS, identities by
    certificate common name: each router trusts the other as a service; robot r1 on B may
    publish its own state to A, not r2's, and gets the fleet's assignment through B."""

    def tls(name: str, **fields: Any) -> Settings:
        return load_settings(
            tls_root_ca=pki.ca, tls_cert=pki.cert(name), tls_key=pki.key(name),
            acl_identity="cert_common_name", **fields,
        )  # fmt: skip

    host = tls(
        "router", listen=["tls/127.0.0.1:0"], acl=True, acl_service_users=["fleet", "site-b"]
    )
    with running_router(host) as (router_a, endpoint_a):
        site = tls(
            "site-b", listen=["tls/127.0.0.1:0"], connect=[endpoint_a],
            acl=True, acl_service_users=["router"], acl_robot_ids=["r1", "r2"],
        )  # fmt: skip
        with (
            running_router(site) as (_router_b, endpoint_b),
            open_session(tls("r1", connect=[endpoint_b]), "client") as r1,
            open_session(tls("fleet", connect=[endpoint_a]), "client") as fleet,
        ):
            at_host = Collector(router_a, KEYS.all_states)
            r1_orders = Collector(r1, KEYS.assignment("r1"))
            own_state, order = (KEYS.state("r1"), b"own"), (KEYS.assignment("r1"), b"order")

            def crossed() -> bool:
                if own_state in at_host.seen() and order in r1_orders.seen():
                    return True
                r1.put(KEYS.state("r2"), b"forged")
                r1.put(*own_state)
                fleet.put(*order)
                return False

            wait_for(crossed, 10.0, "the allowed messages to cross the mesh", poll=0.05)
            at_host.sub.undeclare()
            r1_orders.sub.undeclare()
    assert at_host.seen() == {own_state}
    assert r1_orders.seen() == {order}


def test_simulated_robot_works_under_the_acl(credentials: Path, tmp_path: Path) -> None:
    """A real ``parkfleet sim`` robot with its credentials: its state and liveliness reach
    the service, and the service's assignment reaches it (acknowledged in its state)."""
    router_settings = load_settings(
        listen=["tcp/127.0.0.1:0"], zenoh_credentials_file=credentials, acl=True
    )
    with running_router(router_settings) as (_router, endpoint):
        env = os.environ | {
            "PYTHONUNBUFFERED": "1",
            "PARKFLEET_ZENOH_USER": "r1",
            "PARKFLEET_ZENOH_PASSWORD": PASSWORDS["r1"],
        }
        proc = subprocess.Popen(
            [*CLI, "sim", "--robots", "1", "--id-prefix", "r", "--connect", endpoint],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env,
        )  # fmt: skip
        try:
            service = load_settings(
                connect=[endpoint], zenoh_user="fleet", zenoh_password=PASSWORDS["fleet"]
            )
            with open_session(service, "client") as fleet:
                decoder = Decoder("test")
                states: list[RobotState] = []
                sub = fleet.declare_subscriber(
                    KEYS.all_states,
                    lambda s: states.append(decoder.decode(RobotState, s.payload.to_bytes())),
                )
                order = ParkAssignment(
                    robot_id="r1", task_id="t-acl", goal=Pose(x=1.0, y=0.5, theta=0.0),
                    law="ccw", gains=Gains(kx=1.0, ky=2.0, ktheta=1.0),
                    tolerance=Tolerance(position=0.1, heading=0.1),
                )  # fmt: skip
                # A loaded machine may take a while to start the robot's process.
                wait_for(lambda: bool(states) or proc.poll() is not None, 60.0, "r1's state")
                put_until(
                    fleet,
                    KEYS.assignment("r1"),
                    encode(order),
                    lambda: any(s is not None and s.task_id == "t-acl" for s in states),
                    timeout=20.0,
                )
                tokens = alive_tokens(fleet)
                sub.undeclare()
        finally:
            proc.terminate()
            _, stderr = proc.communicate(timeout=15)
    assert proc.returncode == 0, stderr.decode()
    assert {s.robot_id for s in states if s is not None} == {"r1"}
    assert KEYS.alive("r1") in tokens


@pytest.mark.parametrize(
    "argv",
    [
        ["agent", "--id", "r*", "--drive", "sim", "--connect", "tcp/127.0.0.1:9"],
        ["agent", "--id", "fleet/**", "--drive", "sim", "--connect", "tcp/127.0.0.1:9"],
        ["sim", "--robots", "1", "--id-prefix", "r$", "--connect", "tcp/127.0.0.1:9"],
    ],
)
def test_robot_ids_with_key_expression_wildcards_are_rejected(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert parkfleet_main(argv) == 2
    assert "invalid robot id" in capsys.readouterr().err


# -- operator commands, the link check and ROS 2 traffic under the ACL ----------------------
def _identity_env(identity: str, who: str, pki: Pki) -> dict[str, str]:
    """Environment that makes a ``parkfleet`` child present ``who``'s identity."""
    if identity == "username":
        return {"PARKFLEET_ZENOH_USER": who, "PARKFLEET_ZENOH_PASSWORD": PASSWORDS[who]}
    return {
        "PARKFLEET_TLS_ROOT_CA": str(pki.ca),
        "PARKFLEET_TLS_CERT": str(pki.cert(who)),
        "PARKFLEET_TLS_KEY": str(pki.key(who)),
    }


def _operator(endpoint: str, env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``parkfleet ARGS --connect ENDPOINT`` as an operator would, to the end."""
    return subprocess.run(
        [*CLI, *args, "--connect", endpoint, "--wait", "20"],
        capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL,
        env=os.environ | {"PYTHONUNBUFFERED": "1"} | env,
    )  # fmt: skip


def _mode(watch: Collector, robot: str) -> str | None:
    """The mode in the newest state of ``robot`` a collector received."""
    decoder = Decoder("test")
    with watch.lock:
        samples = list(watch.samples)
    for key, payload in reversed(samples):
        state = decoder.decode(RobotState, payload)
        if key == KEYS.state(robot) and state is not None:
            return state.mode.value
    return None


@pytest.mark.parametrize("identity", ["username", "cert_common_name"])
def test_operator_commands_reach_a_robot_under_the_acl_and_forged_ones_do_not(
    identity: str, pki: Pki, credentials: Path
) -> None:
    """``parkfleet estop | pause | resume`` from an operator identity stop, pause, resume
    and release a simulated robot that has its own identity, each confirmed; robot r2's
    forged release (fleet-wide and addressed to r1) is dropped at the router."""
    from fleet.core.wire import ControlAction
    from fleet.io import operator
    from sim_agent.fleet import SimFleet, Spawn

    router_settings, client = _acl_settings(identity, pki, credentials)
    ops = _identity_env(identity, "ops", pki)
    with (
        running_router(router_settings) as (router, endpoint),
        open_session(client(endpoint, "r1"), "client") as r1,
        open_session(client(endpoint, "r2"), "client") as r2,
        SimFleet(r1, client(endpoint, "r1"), [Spawn("r1", 0.0, 0.0, 0.0)]) as fleet,
    ):
        fleet.start()
        at_router = Collector(router, f"{KEYS.root}/**")
        wait_for(lambda: _mode(at_router, "r1") == "idle", 30.0, "r1's state at the router")

        done = _operator(endpoint, ops, "estop", "--reason", "acl drill")
        assert done.returncode == 0, done.stdout + done.stderr
        assert "r1: confirmed" in done.stdout
        wait_for(lambda: _mode(at_router, "r1") == "estop", 10.0, "r1 e-stopped")

        forged = [
            operator.command(ControlAction.RELEASE, issuer="r2", robot_id=robot)
            for robot in (None, "r1")
        ]
        for message in forged:
            r2.put(KEYS.control(message.robot_id), encode(message))
        fence = (KEYS.state("r2"), b"fence")  # after the forgeries, on r2's own link
        put_until(r2, *fence, lambda: fence in at_router.seen())
        assert not any(payload == encode(m) for m in forged for _, payload in at_router.seen())
        assert _mode(at_router, "r1") == "estop"

        for args, mode in (
            (("pause",), "estop"),  # e-stop wins over pause
            (("estop", "--release"), "paused"),
            (("resume",), "idle"),
        ):
            done = _operator(endpoint, ops, *args)
            assert done.returncode == 0, done.stdout + done.stderr
            assert "r1: confirmed" in done.stdout
            wait_for(lambda m=mode: _mode(at_router, "r1") == m, 10.0, f"r1 {mode}")
        at_router.sub.undeclare()


def test_rest_estop_reaches_a_robot_under_the_acl(credentials: Path, tmp_path: Path) -> None:
    """``parkfleet serve`` as the ACL router (the fleet host of docs/deployment.md): ``POST
    /control/estop`` stops a robot connected with its own credentials, and the release
    frees it; the service sees both."""
    import httpx

    from fleet.io.processes import running_server
    from sim_agent.fleet import SimFleet, Spawn

    env = {
        "PARKFLEET_ACL": "true",
        "PARKFLEET_ZENOH_CREDENTIALS_FILE": str(credentials),
        "PARKFLEET_API_TOKEN": "secret",
    }
    with (
        (tmp_path / "serve.log").open("w") as log,
        running_server(tmp_path / "data", env=env, stderr=log) as server,
    ):
        robot = load_settings(
            connect=[server.zenoh_endpoint], zenoh_user="r1", zenoh_password=PASSWORDS["r1"]
        )
        with (
            open_session(robot, "client") as r1,
            SimFleet(r1, robot, [Spawn("r1", 0.0, 0.0, 0.0)]) as fleet,
            httpx.Client(base_url=server.url, headers={"Authorization": "Bearer secret"}) as api,
        ):
            fleet.start()

            def status() -> str | None:
                reply = api.get("/robots/r1")
                return reply.json()["status"] if reply.status_code == 200 else None

            wait_for(lambda: status() == "idle", 60.0, "r1 to join the service")
            assert api.post("/control/estop", json={"reason": "acl drill"}).status_code == 200
            wait_for(lambda: status() == "estop", 10.0, "r1 e-stopped through the ACL")
            assert api.post("/control/release", json={}).status_code == 200
            wait_for(lambda: status() == "idle", 10.0, "r1 released")


@pytest.mark.parametrize("identity", ["username", "cert_common_name"])
def test_a_lone_robots_link_check_echo_is_answered_under_the_acl(
    identity: str, pki: Pki, credentials: Path
) -> None:
    """The link check's echo (``robot_agent.link``): with no peer and no service, the router's
    reply to a robot's admin-space query is what keeps the robot's link up."""
    from robot_agent.link import LinkMonitor

    router_settings, client = _acl_settings(identity, pki, credentials)
    with (
        running_router(router_settings) as (_router, endpoint),
        open_session(client(endpoint, "r1"), "client") as r1,
    ):
        ticks = [0.0]
        monitor = LinkMonitor(r1, KEYS, timeout_s=3.0, clock=lambda: ticks[0])
        heard_at_start = monitor._last_heard

        def echoed() -> bool:
            ticks[0] += 0.1  # a clock of our own: only an echo reply can move last_heard
            monitor.ok()
            return monitor._last_heard > heard_at_start

        wait_for(echoed, 20.0, "the router's echo reply", poll=0.05)


@pytest.mark.parametrize("identity", ["username", "cert_common_name"])
def test_a_robots_ros2_traffic_crosses_the_acl_router_in_its_namespace_only(
    identity: str, pki: Pki, credentials: Path
) -> None:
    """The robot's rmw_zenoh router pointed at the fleet host (``acl_ros2_namespaces``): the
    drive (robot r1's identity) and the robot's router (the same identity) exchange cmd_vel,
    odometry and ROS-graph tokens under /tb4_1; r2 (namespace /tb4_2) cannot command r1's
    base, and r1's side does not see r2's graph."""
    from robot_agent.drives.ros2_names import data_key, node_token, topic_path

    router_settings, client = _acl_settings(identity, pki, credentials)
    namespaces = {"r1": "/tb4_1", "r2": "/tb4_2"}
    router_settings = router_settings.model_copy(update={"acl_ros2_namespaces": namespaces})
    cmd_vel = data_key("rmw_zenoh", 0, topic_path("rmw_zenoh", "cmd_vel", "/tb4_1"), "a/msg/T", "H")
    odom = data_key("rmw_zenoh", 0, topic_path("rmw_zenoh", "odom", "/tb4_1"), "a/msg/O", "H")
    with (
        running_router(router_settings) as (router, endpoint),
        open_session(client(endpoint, "r1"), "client") as drive,
        open_session(client(endpoint, "r1"), "client") as base,  # the robot's own router
        open_session(client(endpoint, "r2"), "client") as r2,
    ):
        at_router = Collector(router, "0/**")
        at_base = Collector(base, "0/tb4_1/**")
        at_drive = Collector(drive, "0/tb4_1/odom/**")
        token = drive.liveliness().declare_token(node_token(0, "aa", 0, "/tb4_1", "parkfleet_r1"))
        other = r2.liveliness().declare_token(node_token(0, "bb", 0, "/tb4_2", "parkfleet_r2"))

        def forge_and_send() -> None:
            r2.put(cmd_vel, b"forged")
            drive.put(cmd_vel, b"twist")

        def crossed() -> bool:
            if (cmd_vel, b"twist") in at_base.seen() and (odom, b"pose") in at_drive.seen():
                return True
            forge_and_send()
            base.put(odom, b"pose")
            return False

        wait_for(crossed, 10.0, "cmd_vel and odometry to cross the router", poll=0.05)
        fence = (KEYS.state("r2"), b"fence")
        fences = Collector(router, fence[0])
        put_until(r2, *fence, lambda: fence in fences.seen())

        def graph(session: Any) -> set[str]:
            replies = session.liveliness().get("@ros2_lv/0/**", timeout=2.0)
            return {str(reply.ok.key_expr) for reply in replies if reply.ok is not None}

        both = {
            node_token(0, "aa", 0, "/tb4_1", "parkfleet_r1"),
            node_token(0, "bb", 0, "/tb4_2", "parkfleet_r2"),
        }
        wait_for(lambda: graph(router) == both, 10.0, "both robots' graph tokens at the router")
        wait_for(lambda: bool(graph(base)), 10.0, "r1's graph token at its robot's router")
        seen_by_base = graph(base)  # r2's token is at the router by now: it was not forwarded
        token.undeclare()
        other.undeclare()
        for collector in (at_router, at_base, at_drive, fences):
            collector.sub.undeclare()
    assert (cmd_vel, b"forged") not in at_router.seen() | at_base.seen()
    assert seen_by_base == {node_token(0, "aa", 0, "/tb4_1", "parkfleet_r1")}


@pytest.mark.parametrize("identity", ["username", "cert_common_name"])
def test_a_robots_description_reaches_the_service_under_the_acl_and_a_forged_one_does_not(
    identity: str, pki: Pki, credentials: Path
) -> None:
    """A robot puts its own description and answers the service's query for it; r2's put of
    a description for r1 is dropped at the router, and r2 cannot answer for r1."""
    from fleet.core.params import RobotProfile
    from fleet.core.wire import RobotDescription

    router_settings, client = _acl_settings(identity, pki, credentials)
    own = encode(RobotDescription.of("r1", RobotProfile(max_wheel_speed=8.5), model="tb4"))
    forged = encode(RobotDescription.of("r1", RobotProfile(radius=0.01)))
    with (
        running_router(router_settings) as (router, endpoint),
        open_session(client(endpoint, "r1"), "client") as r1,
        open_session(client(endpoint, "r2"), "client") as r2,
        open_session(client(endpoint, "fleet"), "client") as fleet,
    ):
        at_service = Collector(fleet, KEYS.all_descriptions)
        answer = r1.declare_queryable(
            KEYS.description("r1"), lambda query: query.reply(KEYS.description("r1"), own)
        )
        impostor = r2.declare_queryable(
            KEYS.description("r1"), lambda query: query.reply(KEYS.description("r1"), forged)
        )

        def asked() -> set[bytes]:
            replies = fleet.get(KEYS.description("r1"), timeout=2.0)
            return {reply.ok.payload.to_bytes() for reply in replies if reply.ok is not None}

        def put_both() -> bool:
            if (KEYS.description("r1"), own) in at_service.seen():
                return True
            r2.put(KEYS.description("r1"), forged)
            r1.put(KEYS.description("r1"), own)
            return False

        wait_for(put_both, 10.0, "r1's description at the service", poll=0.05)
        fence = (KEYS.state("r2"), b"fence")  # after r2's last forged put, on its link
        fences = Collector(router, fence[0])
        at_service_states = Collector(fleet, KEYS.all_states)
        put_until(r2, *fence, lambda: fence in fences.seen() and fence in at_service_states.seen())
        wait_for(lambda: own in asked(), 10.0, "r1's answer to the service's query")
        answers = asked()
        for handle in (answer, impostor, at_service.sub, fences.sub, at_service_states.sub):
            handle.undeclare()
    assert {payload for _, payload in at_service.seen()} == {own}
    assert answers == {own}
