"""Settings by role: env prefix ``PARKFLEET_``, optional TOML file.

Three models, each the one before plus its role's fields:

- :class:`ZenohSettings` -- what every process needs: the fleet's name, Zenoh endpoints,
  lease, credentials and TLS;
- :class:`RobotSettings` -- a robot computer (``parkfleet agent``): its id, profile,
  control rate, avoidance, holds, drive (sim, ROS 2); no ``api_*``, service or ACL fields;
- :class:`Settings` -- the fleet host and every tool (``serve``, ``sim``, benchmarks): also
  access control, the service and the API.

One TOML file can serve every machine: a robot reading it skips the host's fields
(:class:`RobotSettings` drops keys that only :class:`Settings` knows; anything unknown to
both is still an error), so files written for the single model keep loading.

Precedence (highest first): explicit arguments (CLI flags), ``PARKFLEET_*`` environment
variables, the TOML file named by ``--config`` or ``PARKFLEET_CONFIG``, the defaults here.
Nested fields use ``__`` in the environment, e.g. ``PARKFLEET_PROFILE__MAX_WHEEL_SPEED=15``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated, Any, Literal, Self, TypeVar

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    SecretStr,
    field_validator,
    model_validator,
)
from pydantic_settings import (
    BaseSettings,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
    TomlConfigSettingsSource,
)

from fleet.core.params import Avoidance, RobotProfile, SafetyConfig
from fleet.core.site import Site
from fleet.core.wire import Keys, validate_id
from fleet.io.site_file import load_site

DEFAULT_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
#: The SQLite task database's file name inside ``data_dir`` (spelled here only).
DB_FILE = "parkfleet.db"

_ROS_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
#: A ROS 2 topic name, relative (``cmd_vel``) or absolute (``/tb4_1/cmd_vel``); no ``~``/``{}``.
RosTopicName = Annotated[str, Field(pattern=rf"^/?{_ROS_TOKEN}(/{_ROS_TOKEN})*$")]
#: A ROS 2 namespace: ``""`` or ``"/"`` (the root) or ``/a/b``.
RosNamespace = Annotated[str, Field(pattern=rf"^(/|(/{_ROS_TOKEN})+)?$")]
#: A TF frame id (as in a message header): printable, no whitespace.
FrameId = Annotated[str, Field(pattern=r"^[A-Za-z0-9_./-]{1,256}$")]


class Ros2Settings(BaseModel):
    """The ``ros2`` drive (``robot_agent/drives``): a ROS 2 robot over rmw_zenoh or the
    zenoh-bridge-ros2dds key mapping. TOML table ``[ros2]``, env ``PARKFLEET_ROS2__*``;
    docs/robots.md "Driving a ROS 2 robot" explains every field."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    # How ROS names map to Zenoh keys: rmw_zenoh (``<domain>/<topic>/<type>/<hash>`` plus
    # liveliness tokens) or the bridge (``<namespace>/<topic>``, namespace always prefixed).
    key_mapping: Literal["rmw_zenoh", "bridge"] = "rmw_zenoh"
    # ROS 2 distribution of the robot: jazzy (and later: RIHS01 type hashes in keys) or humble.
    distro: Literal["jazzy", "humble"] = "jazzy"
    domain_id: Annotated[int, Field(ge=0, le=232)] = 0  # ROS_DOMAIN_ID of the robot
    namespace: RosNamespace = ""  # the robot's namespace, e.g. "/tb4_1"; relative topics join it
    node_name: Annotated[str, Field(pattern=rf"^{_ROS_TOKEN}$")] | None = None  # parkfleet_<id>
    cmd_vel_topic: RosTopicName = "cmd_vel"
    cmd_vel_type: Literal["geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"] = (
        "geometry_msgs/msg/Twist"
    )
    base_frame_id: FrameId = "base_link"  # header.frame_id of a TwistStamped command
    # "odometry": the pose is nav_msgs/Odometry on odom_topic (frame odom_frame_id);
    # "localiser": a localiser's PoseWithCovarianceStamped on localiser_topic (frame
    # localiser_frame_id), carried forward between its updates by the odometry.
    pose_source: Literal["odometry", "localiser"] = "odometry"
    odom_topic: RosTopicName = "odom"
    odom_frame_id: FrameId = "odom"
    localiser_topic: RosTopicName = "amcl_pose"
    localiser_frame_id: FrameId = "map"
    # Pose of the pose frame (odom or map) in the fleet's world frame: x [m], y [m], theta [rad].
    origin: tuple[
        Annotated[float, Field(allow_inf_nan=False)],
        Annotated[float, Field(allow_inf_nan=False)],
        Annotated[float, Field(allow_inf_nan=False)],
    ] = (0.0, 0.0, 0.0)
    # The robot's Zenoh router; [] = the agent's own endpoints and security settings.
    connect: list[str] = Field(default_factory=list)
    # A message stamped more than this [s] ahead of this computer's clock is dropped.
    max_future_s: Annotated[float, Field(ge=0, le=10)] = 0.1
    # parkfleet agent waits this long [s] for the first usable pose, then exits with a reason.
    first_pose_timeout_s: Annotated[float, Field(gt=0)] = 30.0
    # Odometry jump (docs/robots.md "Where the two links go"): consecutive odometry poses
    # farther apart than the profile's top speed x their stamps' interval + odom_jump_m [m]
    # (or turned more than its top turn rate x interval + odom_jump_rad [rad]), or odometry
    # back at its origin, hold the robot with a pose_jump fault until re-aligned.
    odom_jump_m: Annotated[float, Field(gt=0)] = 0.25
    odom_jump_rad: Annotated[float, Field(gt=0)] = 0.5
    # An odometry stamp this far [s] behind the newest, but near this computer's clock, is a
    # clock stepped back (NTP, no RTC): the drive re-bases instead of dropping every pose.
    clock_step_s: Annotated[float, Field(gt=0)] = 1.0


class ZenohSettings(BaseSettings):
    """What every process needs to join the fleet's Zenoh network; see docs/deployment.md
    "Configuration"."""

    model_config = SettingsConfigDict(
        env_prefix="PARKFLEET_", env_nested_delimiter="__", extra="forbid", validate_default=True
    )

    config_file: Path | None = Field(default=None, exclude=True)

    # Zenoh
    fleet_name: str = "default"
    zenoh_mode: Literal["router", "peer", "client"] | None = None  # None: role decides
    listen: list[str] = Field(default_factory=list)
    connect: list[str] = Field(default_factory=list)
    # Transport lease [ms]: how fast a hung (not killed) peer is seen gone.
    lease_ms: Annotated[int, Field(ge=100)] = 1000
    # Security (docs/deployment.md). Credentials this session presents when it connects:
    zenoh_user: str | None = None
    zenoh_password: SecretStr | None = None
    # usrpwd dictionary (``user:password`` per line) a listening router checks; setting it
    # makes the router refuse every session without valid credentials.
    zenoh_credentials_file: Path | None = None
    # TLS for ``tls/`` endpoints: the CA that signs every certificate of the deployment,
    # and this process's certificate and key. With cert + key, mutual TLS is on: a
    # listener refuses clients without a certificate signed by the CA.
    tls_root_ca: Path | None = None
    tls_cert: Path | None = None
    tls_key: Path | None = None
    tls_verify_name: bool = True  # check the router's certificate names the address dialled

    @model_validator(mode="before")
    @classmethod
    def _skip_other_roles_fields(cls, data: Any) -> Any:
        """Drop the keys of a larger role's fields (a host's ``api_port`` in a file a robot
        reads too); a key no role knows still fails (``extra="forbid"``)."""
        if not isinstance(data, dict) or cls is Settings:
            return data
        others = Settings.model_fields.keys() - cls.model_fields.keys()
        return {k: v for k, v in data.items() if k not in others}

    @field_validator("fleet_name")
    @classmethod
    def _fleet_name_is_key_safe(cls, value: str) -> str:
        return validate_id(value, "fleet name")

    @model_validator(mode="after")
    def _security_settings_come_in_pairs(self) -> Self:
        if (self.zenoh_user is None) != (self.zenoh_password is None):
            raise ValueError("zenoh_user and zenoh_password must be set together")
        if (self.tls_cert is None) != (self.tls_key is None):
            raise ValueError("tls_cert and tls_key must be set together")
        if self.tls_cert is not None and self.tls_root_ca is None:
            raise ValueError("tls_cert needs tls_root_ca (the CA that signs the peers' certs)")
        return self

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        sources: list[PydanticBaseSettingsSource] = [init_settings, env_settings]
        toml_path = os.environ.get("PARKFLEET_CONFIG")
        if toml_path:
            sources.append(TomlConfigSettingsSource(settings_cls, toml_file=Path(toml_path)))
        return tuple(sources)


class RobotSettings(ZenohSettings):
    """A robot computer's settings (``parkfleet agent``): no host fields."""

    # Robot agent
    robot_id: str | None = None
    control_rate_hz: Annotated[float, Field(gt=0, le=1000)] = 50.0
    profile: RobotProfile = RobotProfile()
    # What the robot says of itself on ``robot/<id>/description`` (docs/operating.md
    # "Robots describe themselves"): whether its base may drive backwards, and a model name
    # for people.
    may_reverse: bool = True
    robot_model: Annotated[str, Field(max_length=64)] | None = None
    avoidance: Avoidance = Avoidance()
    safety: SafetyConfig = SafetyConfig()  # docs/safety.md: the filter and its assumptions
    pose_stale_s: Annotated[float, Field(gt=0)] = 0.5  # own pose older than this -> stop
    # Router link silent this long (no peer, service or echo reply) -> hold; a silent peer
    # is never forgotten: it stays an obstacle at its last pose. At most
    # safety.peer_stale_s: peers take a robot silent that long as stopped (docs/safety.md).
    link_timeout_s: Annotated[float, Field(gt=0)] = 3.0
    # State streams (fleet/core/wire.py): the peer stream at control_rate_hz under grid cells
    # of peer_cell_m [m] (None: twice avoidance.peer_radius; the same for every robot of a
    # fleet), and the fleet-rate stream the service reads at fleet_rate_hz (and at once on
    # a change of mode, task or faults); "json" states for a service of an older release.
    peer_cell_m: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    fleet_rate_hz: Annotated[float, Field(gt=0, le=1000)] = 10.0
    state_encoding: Literal["compact", "json"] = "compact"
    # Drive of ``parkfleet agent``: ``module:factory`` or a name in DRIVES ("sim"), and the
    # simulated drive's start posture (x [m], y [m], theta [rad]).
    drive: str | None = None
    sim_start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # the ``ros2`` drive (docs/robots.md "Driving a ROS 2 robot")
    ros2: Ros2Settings = Ros2Settings()

    @property
    def cell_m(self) -> float:
        """[m] grid cell of the peer stream: ``peer_cell_m``, else twice the peer radius
        (the peer radius of Eq. (27) plus as much again for motion, fleet/core/wire.py)."""
        return self.peer_cell_m or 2.0 * self.avoidance.peer_radius

    def keys(self) -> Keys:
        """The key expressions of this fleet (its name and cell size)."""
        return Keys(self.fleet_name, self.cell_m)

    @field_validator("robot_id")
    @classmethod
    def _robot_id_is_key_safe(cls, value: str | None) -> str | None:
        return None if value is None else validate_id(value)

    @model_validator(mode="after")
    def _silent_robots_stop_before_peers_call_them_stopped(self) -> Self:
        if self.link_timeout_s > self.safety.peer_stale_s:
            raise ValueError(
                f"link_timeout_s ({self.link_timeout_s:g} s) must be at most "
                f"safety.peer_stale_s ({self.safety.peer_stale_s:g} s): a robot cut off holds "
                "after link_timeout_s, and its peers take it as stopped after peer_stale_s"
            )
        return self


class Settings(RobotSettings):
    """Every tunable of parkfleet (the fleet host's and every tool's); see
    docs/deployment.md "Configuration" for the list."""

    # Access control on a router (fleet/acl.py): default deny; a robot may publish only its
    # own state and liveliness; only service identities may send assignments.
    acl: bool = False
    acl_identity: Literal["username", "cert_common_name"] = "username"
    acl_robot_ids: list[str] = Field(default_factory=list)  # [] -> the credentials file's users
    acl_service_users: list[str] = Field(default_factory=lambda: ["fleet"])
    # Operators' tools (parkfleet estop | pause | resume): operator commands and states only.
    acl_operator_users: list[str] = Field(default_factory=list)
    acl_file: Path | None = None  # a hand-written access_control block (JSON5) used verbatim
    # Robots whose ROS 2 traffic crosses this router (the robot's rmw_zenoh router pointed
    # at the fleet host): robot id -> its ROS namespace, on ROS domain acl_ros2_domain_id.
    acl_ros2_namespaces: dict[str, RosNamespace] = Field(default_factory=dict)
    acl_ros2_domain_id: Annotated[int, Field(ge=0, le=232)] = 0

    # Fleet service / API
    data_dir: Path = Path("var")
    # Task store: unset = SQLite at data_dir/parkfleet.db; a path = that SQLite file;
    # ``postgresql://...`` = PostgreSQL, shared by a leader and its standbys
    # (docs/deployment.md "Standby and fencing"). Leader lease [s]: a leader that cannot
    # reach PostgreSQL stops commanding within it; a standby tries to take over every
    # leader_poll_s [s]; advertise_url is the API address a standby names for this service
    # when it leads (default: its own URL).
    store: str | None = None
    leader_lease_s: Annotated[float, Field(gt=0)] = 3.0
    leader_poll_s: Annotated[float, Field(gt=0)] = 0.1
    advertise_url: str | None = None
    api_host: str = "127.0.0.1"
    api_port: Annotated[int, Field(ge=0, le=65535)] = 8000
    api_token: SecretStr | None = None
    # API limits (docs/rest-api.md): what one client can make the server hold or do.
    api_max_body_bytes: Annotated[int, Field(ge=1024)] = 262_144  # request body, 413 beyond
    api_tasks_page_max: Annotated[int, Field(ge=1, le=10_000)] = 1000  # GET /tasks page size
    api_sse_max_clients: Annotated[int, Field(ge=1)] = 32  # open /events streams, 503 beyond
    api_sse_queue_frames: Annotated[int, Field(ge=16)] = 2000  # per client; dropped beyond
    api_plot_cache_entries: Annotated[int, Field(ge=1)] = 64  # rendered plot.png kept
    api_plot_renders_per_s: Annotated[float, Field(gt=0)] = 2.0  # plot renders, 429 beyond
    api_plot_render_burst: Annotated[int, Field(ge=1)] = 5  # renders allowed at once
    # Yard rectangle: x_min, x_max, y_min, y_max [m]; goals outside it are rejected.
    yard: tuple[float, float, float, float] = (-10.0, 10.0, -10.0, 10.0)
    task_timeout_s: Annotated[float, Field(gt=0)] = 120.0
    on_robot_lost: Literal["fail", "requeue"] = "fail"
    safety_separation_m: Annotated[float, Field(gt=0)] = 0.5
    # A task whose robot makes no progress towards the goal this long is stuck: recovered
    # (flip, wait, requeue to another robot), then failed (fleet/service/stuck.py).
    stuck_after_s: Annotated[float, Field(gt=0)] = 30.0
    # A robot reporting ``avoiding`` with no progress this long [s, on its own clock: its
    # state seq over the control rate] is in a standoff: the service makes one robot of
    # each standoff give way (a held revision, the other law), for a plan to resume.
    standoff_after_s: Annotated[float, Field(gt=0)] = 8.0
    # [m] what counts as progress in that window: a robot held off by another creeps and
    # dithers, a few centimetres nearer its goal now and then, and stays in the standoff.
    standoff_progress_m: Annotated[float, Field(gt=0, le=5.0)] = 0.25
    # A robot alone (no robot within the peer radius) within a post's influence radius,
    # ``avoiding`` with no progress this long [s, its own time], is held by the posts'
    # Eq. (27) terms, which no waiting undoes: its first stuck recovery comes then (flip,
    # routed round the posts' zones) instead of after ``standoff_after_s``.
    post_stall_after_s: Annotated[float, Field(gt=0)] = 3.0
    # Site map (fleet/core/site.py: yard, obstacles, keep-out zones, bays), TOML or JSON;
    # its yard replaces ``yard``. Loaded and checked when the settings are.
    site_file: Path | None = None
    _site: Site | None = PrivateAttr(default=None)
    # Receding horizon: the planner runs again every replan_period_s [s] of the robots' time
    # (their measured time scale: a simulation at 5x is planned for 5x as often on the
    # service's clock, never less often than every replan_period_s of it), when a robot is
    # farther than replan_corridor_m [m] from its predicted path at the same robot time, and
    # when two robots (one moving) come closer than safety_separation_m + this margin [m].
    replan_period_s: Annotated[float, Field(gt=0)] = 2.0
    #: Plan in a process of its own (fleet/service/planner_process.py), so planning never
    #: holds the GIL the API's requests and the robots' messages need (the default); off:
    #: on the planner worker's thread.
    planner_process: bool = True
    #: Passages the walls and posts make too narrow for two robots to pass are single-robot
    #: zones, beside the site map's own (fleet/core/planner/passages.py).
    narrow_passages: bool = True
    replan_corridor_m: Annotated[float, Field(gt=0)] = 0.3
    replan_separation_margin_m: Annotated[float, Field(ge=0)] = 0.2
    # Retention: a robot lost this long [s] is forgotten (an operator may remove it sooner,
    # DELETE /robots/{id}); finished tasks are deleted from the store this long [s] after
    # they ended (default 30 days).
    lost_robot_retention_s: Annotated[float, Field(gt=0)] = 3600.0
    finished_task_retention_s: Annotated[float, Field(gt=0)] = 30 * 86400.0
    # The server's C heap (fleet/io/heap.py: without these its resident size grows with the
    # work done): at most this many malloc arenas (0: the C library's default, 8 per core),
    # and its free pages given back to the kernel this often [s] (0: never).
    malloc_arenas: Annotated[int, Field(ge=0)] = 2
    heap_trim_interval_s: Annotated[float, Field(ge=0)] = 60.0

    @field_validator("acl_robot_ids", "acl_service_users", "acl_operator_users")
    @classmethod
    def _acl_ids_are_key_safe(cls, value: list[str]) -> list[str]:
        return [validate_id(v, "access-control id") for v in value]

    @field_validator("acl_ros2_namespaces")
    @classmethod
    def _acl_ros2_robots_are_key_safe(cls, value: dict[str, str]) -> dict[str, str]:
        return {validate_id(robot, "access-control id"): ns for robot, ns in value.items()}

    @model_validator(mode="after")
    def _load_site(self) -> Settings:
        if self.site_file is None:
            return self
        site = load_site(
            self.site_file,
            robot_radius=self.profile.radius,
            peer_radius=self.avoidance.peer_radius,
        )
        if "yard" in self.model_fields_set and tuple(self.yard) != site.yard.as_tuple():
            raise ValueError(
                f"yard {self.yard} is set and so is the site file {self.site_file}'s yard "
                f"{site.yard.as_tuple()}: set one of them"
            )
        self.yard = site.yard.as_tuple()
        self._site = site
        return self

    @property
    def db_path(self) -> Path:
        """The fleet's SQLite task database: ``<data_dir>/parkfleet.db``."""
        return self.data_dir / DB_FILE

    @property
    def site(self) -> Site | None:
        """The site map of ``site_file`` (None without one)."""
        return self._site

    def with_site(self, site: Site) -> Settings:
        """A copy running with ``site``, its yard included: a site map built in code (the
        fleet bench's scenarios) rather than read from ``site_file``."""
        copy = self.model_copy(update={"yard": site.yard.as_tuple(), "site_file": None})
        copy._site = site
        return copy


_S = TypeVar("_S", bound=ZenohSettings)


def load_settings(config_file: Path | None = None, **overrides: Any) -> Settings:
    """Settings (every field: the fleet host, tools) from an optional TOML file, the
    environment and explicit overrides.

    ``None`` overrides are ignored so CLI flags left unset fall through to lower layers.
    """
    return load_role(Settings, config_file, **overrides)


def load_robot_settings(config_file: Path | None = None, **overrides: Any) -> RobotSettings:
    """A robot computer's settings (:class:`RobotSettings`), as :func:`load_settings`."""
    return load_role(RobotSettings, config_file, **overrides)


def load_role(model: type[_S], config_file: Path | None = None, **overrides: Any) -> _S:
    """Settings of one role's ``model`` from an optional TOML file, the environment and
    explicit overrides (``None`` overrides ignored)."""
    given = {k: v for k, v in overrides.items() if v is not None}
    if config_file is None:
        return model(**given)
    if not config_file.is_file():
        raise FileNotFoundError(f"config file not found: {config_file}")

    class _FromFile(model):  # type: ignore[valid-type,misc]
        @classmethod
        def settings_customise_sources(
            cls,
            settings_cls: type[BaseSettings],
            init_settings: PydanticBaseSettingsSource,
            env_settings: PydanticBaseSettingsSource,
            dotenv_settings: PydanticBaseSettingsSource,
            file_secret_settings: PydanticBaseSettingsSource,
        ) -> tuple[PydanticBaseSettingsSource, ...]:
            return (
                init_settings,
                env_settings,
                TomlConfigSettingsSource(settings_cls, toml_file=config_file),
            )

    loaded = _FromFile(**given)
    return model.model_validate(loaded.model_dump() | {"config_file": config_file})
