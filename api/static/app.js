// parkfleet fleet console: live map, robots, tasks, and parking goals placed on the map.
//
// Data flow: the /events stream (robot states at <= 10 Hz per robot, task changes) only
// fills `pending` maps (latest wins per robot / task). Once per animation frame the
// pending changes are applied to `state`, the canvas is redrawn if anything changed, and
// the tables are patched in place (robots at most 4 times a second). That keeps the page
// smooth with 50 robots: no work per event beyond a JSON parse and a map write.

import { api, ApiError, EventStream, idempotencyKey, loadToken, saveToken } from "./api.js";
import { LAW_COLORS, MODE_COLORS, YardMap } from "./map.js";

const TRAIL_POINTS = 300; // per robot; older points are dropped
const TRAIL_STEP_M = 0.03; // a new trail point once the robot moved this far
const TASKS_FETCHED = 200; // newest tasks loaded on (re)connection
const TASKS_KEPT = 400; // finished tasks beyond this are forgotten (oldest first)
const ROBOT_TABLE_MS = 250;
const OBSTACLES_POLL_MS = 10000; // obstacles have no event: poll them
const OPERATOR_POLL_MS = 2000; // bays and the operator's holds: polled, and after task events
const LEVEL_ORDER = { fatal: 0, error: 1, warning: 2 };
const SMOOTHING_S = 0.08; // display pose follows the reported one with this time constant
const ACTIVE = new Set(["queued", "assigned", "driving", "waiting"]);
const EQUATION = { ccw: "Eq. (17)", cw: "Eq. (20)" };

const $ = (id) => document.getElementById(id);
const naturalOrder = new Intl.Collator(undefined, { numeric: true }).compare;

/** Fixed-size ring of trail points [m]. */
class Trail {
  constructor(capacity) {
    this.xs = new Float64Array(capacity);
    this.ys = new Float64Array(capacity);
    this.capacity = capacity;
    this.start = 0;
    this.length = 0;
  }
  clear() {
    this.start = 0;
    this.length = 0;
  }
  push(x, y) {
    if (this.length > 0) {
      const last = (this.start + this.length - 1) % this.capacity;
      if (Math.hypot(x - this.xs[last], y - this.ys[last]) < TRAIL_STEP_M) return;
    }
    const at = (this.start + this.length) % this.capacity;
    this.xs[at] = x;
    this.ys[at] = y;
    if (this.length < this.capacity) this.length += 1;
    else this.start = (this.start + 1) % this.capacity;
  }
  forEachPoint(fn) {
    for (let i = 0; i < this.length; i += 1) {
      const k = (this.start + i) % this.capacity;
      fn(this.xs[k], this.ys[k], i);
    }
  }
}

const state = {
  config: { fleet_name: "", yard: [-10, 10, -10, 10], robot_radius: 0.2, peer_radius: 1, auth: false },
  robots: new Map(), // id -> robot record (see applyRobot)
  tasks: new Map(), // id -> TaskOut
  obstacles: [],
  site: null, // GET /site: yard, obstacles, keep_out, bays (null: no site map)
  bays: [], // GET /bays: name, group, pose, status (free / reserved / occupied)
  zones: [], // GET /zones: single-robot zones, name, polygon, found, robot_ids (holding it)
  control: { fleet: { paused: false, estop: false }, robots: {} }, // GET /control
  connection: "connecting",
  draft: null, // {x, y, theta} [m, m, rad]
  draftKey: idempotencyKey(),
  highlight: null, // robot id
  options: { trails: true, labels: true, peers: false },
  frames: 0,
  events: 0,
  workMs: 0,
  workMaxMs: 0,
  loads: 0, // full state loads: one per (re)connection of the event stream
};

const pending = { robots: new Map(), tasks: new Map() };
const dirty = {
  map: true,
  robotTable: true,
  robotSet: true,
  tasks: new Set(),
  taskOrder: true,
  faults: true,
  operator: true,
};

// --- state updates -----------------------------------------------------------------

function applyRobot(data) {
  let robot = state.robots.get(data.robot_id);
  if (!robot) {
    robot = {
      id: data.robot_id,
      trail: new Trail(TRAIL_POINTS),
      display: { x: data.pose.x, y: data.pose.y, theta: data.pose.theta },
    };
    state.robots.set(data.robot_id, robot);
    dirty.robotSet = true;
  }
  if (data.task_id && data.task_id !== robot.task_id) robot.trail.clear(); // a new task's path
  robot.status = data.status;
  robot.pose = data.pose;
  robot.u = data.u;
  robot.omega = data.omega;
  robot.task_id = data.task_id;
  robot.law = data.law;
  robot.goal = data.goal;
  robot.radius = data.radius; // its own body (described), else what its state says
  robot.described = data.described ?? false;
  robot.model = data.model ?? null;
  robot.max_speed = data.max_speed ?? null;
  robot.may_reverse = data.may_reverse ?? true;
  robot.last_seen = data.last_seen;
  if (robot.detail !== data.detail || JSON.stringify(robot.errors) !== JSON.stringify(data.errors ?? [])) {
    dirty.faults = true;
    dirty.operator = true;
  }
  robot.detail = data.detail ?? null;
  robot.errors = data.errors ?? [];
  robot.trail.push(data.pose.x, data.pose.y);
  dirty.map = true;
  dirty.robotTable = true;
}

function applyTask(task) {
  const known = state.tasks.get(task.id);
  if (known && known.updated_at > task.updated_at) return; // a stale copy (fetch raced an event)
  if (!known) dirty.taskOrder = true;
  state.tasks.set(task.id, task);
  dirty.tasks.add(task.id);
  dirty.map = true;
}

function forgetOldTasks() {
  if (state.tasks.size <= TASKS_KEPT) return;
  const finished = [...state.tasks.values()]
    .filter((t) => !ACTIVE.has(t.status))
    .sort((a, b) => a.created_at - b.created_at);
  for (const task of finished.slice(0, state.tasks.size - TASKS_KEPT)) {
    state.tasks.delete(task.id);
    taskRows.get(task.id)?.remove();
    taskRows.delete(task.id);
  }
}

function drainPending() {
  if (pending.robots.size) {
    for (const data of pending.robots.values()) applyRobot(data);
    pending.robots.clear();
  }
  if (pending.tasks.size) {
    for (const task of pending.tasks.values()) applyTask(task);
    pending.tasks.clear();
    forgetOldTasks();
  }
}

/** Move each robot's displayed pose towards its reported one; true while any moves. */
function smooth(dt) {
  const k = 1 - Math.exp(-dt / SMOOTHING_S);
  let moving = false;
  for (const robot of state.robots.values()) {
    const d = robot.display;
    const p = robot.pose;
    const dx = p.x - d.x;
    const dy = p.y - d.y;
    const dth = Math.atan2(Math.sin(p.theta - d.theta), Math.cos(p.theta - d.theta));
    if (Math.hypot(dx, dy) > 3 || (Math.abs(dx) < 1e-4 && Math.abs(dy) < 1e-4 && Math.abs(dth) < 1e-3)) {
      d.x = p.x; // far jump (new robot, reconnection) or settled: snap
      d.y = p.y;
      d.theta = p.theta;
      continue;
    }
    d.x += k * dx;
    d.y += k * dy;
    d.theta += k * dth;
    moving = true;
  }
  return moving;
}

// --- loading and the live stream -----------------------------------------------------

async function refetchAll() {
  state.loads += 1;
  try {
    const [config, robots, tasks, obstacles] = await Promise.all([
      api.config(),
      api.robots(),
      api.tasks(TASKS_FETCHED),
      api.obstacles(),
    ]);
    state.site = config.site ? await api.site() : null;
    await refreshOperator();
    applyConfig(config);
    const present = new Set(robots.map((r) => r.robot_id));
    for (const id of [...state.robots.keys()]) {
      if (!present.has(id)) state.robots.delete(id);
    }
    robots.forEach(applyRobot);
    tasks.forEach(applyTask);
    forgetOldTasks();
    state.obstacles = obstacles;
    dirty.robotSet = true;
    dirty.map = true;
  } catch (err) {
    console.warn("parkfleet: could not load the fleet state", err);
  }
}

function applyConfig(config) {
  const yardChanged = String(config.yard) !== String(state.config.yard);
  state.config = config;
  if (yardChanged) map.setYard(config.yard);
  $("fleet-name").textContent = config.fleet_name ? `fleet ${config.fleet_name}` : "";
  $("token-form").dataset.required = String(config.auth);
  dirty.map = true;
}

const SERVICE_POLL_MS = 5000;

/** Which fleet service this console talks to: its address, and with a PostgreSQL store its
 * role (a standby's writes are refused with 503 and the leader's address) and term. */
async function pollService() {
  try {
    const h = await api.health();
    const role = h.store === "postgresql"
      ? (h.role === "leader" ? ` · leader, term ${h.term}` : ` · standby (leader ${h.leader || "none yet"})`)
      : "";
    $("service-id").textContent = `service ${location.host}${role}`;
    $("service-id").dataset.role = h.role;
  } catch {
    $("service-id").textContent = `service ${location.host} · unreachable`;
  }
  setTimeout(pollService, SERVICE_POLL_MS);
}

async function pollObstacles() {
  if (state.connection === "live") {
    try {
      state.obstacles = await api.obstacles();
      dirty.map = true;
    } catch {
      /* the stream's indicator already shows trouble */
    }
  }
  setTimeout(pollObstacles, OBSTACLES_POLL_MS);
}

/** The site's bays: none without a site map (GET /bays is a 404 then, not asked for). */
async function fetchBays() {
  if (!state.site) return [];
  try {
    return await api.bays();
  } catch (err) {
    if (err instanceof ApiError && err.status === 404) return []; // restarted without a site
    throw err;
  }
}

/** Bays, single-robot zones and the operator's holds (no events carry them). */
async function refreshOperator() {
  try {
    const [bays, zones, control] = await Promise.all([fetchBays(), api.zones(), api.controlState()]);
    state.bays = bays;
    state.zones = zones;
    state.control = control;
    dirty.map = true;
    dirty.operator = true;
  } catch {
    /* the stream's indicator already shows trouble */
  }
}

let operatorTimer = null;
function refreshOperatorSoon() {
  if (operatorTimer === null) {
    operatorTimer = setTimeout(() => {
      operatorTimer = null;
      refreshOperator();
    }, 250);
  }
}

async function pollOperator() {
  if (state.connection === "live") await refreshOperator();
  setTimeout(pollOperator, OPERATOR_POLL_MS);
}

function setConnection(value) {
  state.connection = value;
  const el = $("conn");
  el.dataset.state = value;
  $("conn-text").textContent =
    { connecting: "connecting…", live: "live", reconnecting: "reconnecting…", offline: "offline" }[value] ??
    value;
}

const stream = new EventStream("events", {
  onOpen: refetchAll,
  onState: setConnection,
  onEvent(type, data) {
    state.events += 1;
    if (type === "robot") pending.robots.set(data.robot_id, data);
    else {
      pending.tasks.set(data.id, data);
      if (data.bay) refreshOperatorSoon(); // a bay changed hands
    }
  },
});

// --- map -----------------------------------------------------------------------------

const canvas = $("map");
const map = new YardMap(canvas);
map.setYard(state.config.yard);

function goalsToDraw() {
  const goals = [];
  const shown = new Set();
  for (const task of state.tasks.values()) {
    if (!ACTIVE.has(task.status)) continue;
    shown.add(task.id);
    goals.push({
      ...task.goal,
      law: task.law,
      robotId: task.robot_id,
      queued: task.status === "queued",
      route: task.route ?? [],
    });
  }
  for (const robot of state.robots.values()) {
    // A goal whose task is older than the loaded list, or whose event is still in flight.
    const task = state.tasks.get(robot.task_id);
    const finished = task && !ACTIVE.has(task.status);
    const moving = robot.status === "driving" || robot.status === "avoiding";
    if (robot.goal && robot.task_id && !shown.has(robot.task_id) && !finished && moving) {
      goals.push({ ...robot.goal, law: robot.law, robotId: robot.id, queued: false });
    }
  }
  return goals;
}

function drawMap() {
  const robots = [...state.robots.values()];
  map.draw({
    robots,
    goals: goalsToDraw(),
    obstacles: state.obstacles,
    site: state.site,
    bays: state.bays,
    zones: state.zones,
    draft: state.draft,
    options: state.options,
    robotRadius: state.config.robot_radius,
    peerRadius: state.config.peer_radius,
    highlight: state.highlight,
  });
}

let drag = null; // {px, py, moved} while the pointer is down on the map

function pointerWorld(event) {
  const rect = canvas.getBoundingClientRect();
  return map.toWorld(event.clientX - rect.left, event.clientY - rect.top);
}

canvas.addEventListener("pointerdown", (event) => {
  if (event.button !== 0) return;
  const [x, y] = pointerWorld(event);
  if (!map.insideYard(x, y)) {
    showMessage("form-message", "That point is outside the yard.", "error");
    return;
  }
  canvas.setPointerCapture(event.pointerId);
  drag = { px: event.clientX, py: event.clientY, moved: false };
  setDraft({ x: round(x, 2), y: round(y, 2), theta: state.draft?.theta ?? 0 });
});

canvas.addEventListener("pointermove", (event) => {
  const [x, y] = pointerWorld(event);
  $("cursor").textContent = map.insideYard(x, y)
    ? `x ${x.toFixed(2)}, y ${y.toFixed(2)} m`
    : "outside the yard";
  if (!drag) return;
  const dx = event.clientX - drag.px;
  const dy = event.clientY - drag.py;
  if (!drag.moved && Math.hypot(dx, dy) < 6) return;
  drag.moved = true;
  setDraft({ ...state.draft, theta: Math.atan2(-dy, dx) }); // canvas y points down
});

for (const type of ["pointerup", "pointercancel"]) {
  canvas.addEventListener(type, () => {
    drag = null;
  });
}
canvas.addEventListener("pointerleave", () => {
  $("cursor").textContent = "x —, y — m";
});

// --- the task form -----------------------------------------------------------------

function round(value, digits) {
  const f = 10 ** digits;
  return Math.round(value * f) / f;
}

function wrapDegrees(deg) {
  const w = ((((deg + 180) % 360) + 360) % 360) - 180;
  return w === -180 ? 180 : w;
}

function setDraft(draft, { fromForm = false } = {}) {
  state.draft = draft;
  state.draftKey = idempotencyKey(); // a changed goal is a new request
  dirty.map = true;
  if (!fromForm && draft) {
    $("goal-x").value = draft.x.toFixed(2);
    $("goal-y").value = draft.y.toFixed(2);
    $("goal-theta").value = String(round(wrapDegrees((draft.theta * 180) / Math.PI), 1));
  }
  showMessage("form-message", "");
}

function draftFromForm() {
  const x = Number.parseFloat($("goal-x").value);
  const y = Number.parseFloat($("goal-y").value);
  const deg = Number.parseFloat($("goal-theta").value || "0");
  if (![x, y, deg].every(Number.isFinite)) return null;
  return { x, y, theta: (wrapDegrees(deg) * Math.PI) / 180 };
}

for (const id of ["goal-x", "goal-y", "goal-theta"]) {
  $(id).addEventListener("input", () => setDraft(draftFromForm(), { fromForm: true }));
}

function clearDraft() {
  state.draft = null;
  for (const id of ["goal-x", "goal-y"]) $(id).value = "";
  $("goal-theta").value = "0";
  dirty.map = true;
}

$("clear-draft").addEventListener("click", () => {
  clearDraft();
  showMessage("form-message", "");
});

document.addEventListener("keydown", (event) => {
  if (event.key === "Escape" && !$("task-dialog").open) clearDraft();
});

function showMessage(id, text, kind = "info") {
  const el = $(id);
  el.textContent = text;
  el.dataset.kind = kind;
}

function currentToken() {
  return $("token").value.trim();
}

$("task-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const draft = draftFromForm();
  if (!draft) {
    showMessage("form-message", "Place a goal on the map (or type x and y) first.", "error");
    return;
  }
  if (!map.insideYard(draft.x, draft.y)) {
    const [xmin, xmax, ymin, ymax] = state.config.yard;
    showMessage("form-message", `The goal must lie in the yard: x ∈ [${xmin}, ${xmax}], y ∈ [${ymin}, ${ymax}] m.`, "error");
    return;
  }
  const body = { goal: { x: draft.x, y: draft.y, theta: draft.theta }, direction: $("goal-direction").value };
  const robot = $("goal-robot").value;
  if (robot) body.robot_id = robot;
  const button = $("submit-task");
  button.disabled = true;
  showMessage("form-message", "Submitting…");
  try {
    const task = await api.submitTask(body, currentToken(), state.draftKey);
    applyTask(task);
    clearDraft();
    state.draftKey = idempotencyKey();
    showMessage("form-message", `Task ${shortId(task.id)} ${task.status}.`, "ok");
  } catch (err) {
    if (err instanceof ApiError && err.status === 401) {
      showMessage("form-message", "The API needs a token: enter it at the top right.", "error");
      $("token").focus();
    } else {
      showMessage("form-message", err instanceof ApiError ? err.message : "The server is unreachable.", "error");
    }
  } finally {
    button.disabled = false;
  }
});

$("token").value = loadToken();
$("token-form").addEventListener("submit", (event) => {
  event.preventDefault();
  saveToken(currentToken());
  showMessage("form-message", currentToken() ? "Token saved in this browser." : "Token cleared.", "ok");
});

// --- tables --------------------------------------------------------------------------

function shortId(id) {
  return id.length > 8 ? id.slice(0, 8) : id;
}

function formatPose(p) {
  if (!p) return "—";
  const deg = wrapDegrees((p.theta * 180) / Math.PI);
  return `${p.x.toFixed(2)}, ${p.y.toFixed(2)}, ${deg.toFixed(0)}°`;
}

function lawBadge(law) {
  if (!(law in EQUATION)) return '<span class="law law-none">—</span>';
  return `<span class="law law-${law}" title="${EQUATION[law]}">${law}</span>`;
}

const cellHtml = new WeakMap(); // what each cell was last given (cheaper than reading innerHTML)

function setCell(cell, html) {
  if (cellHtml.get(cell) === html) return;
  cellHtml.set(cell, html);
  cell.innerHTML = html;
}

const robotRows = new Map();

function renderRobotSelect() {
  const select = $("goal-robot");
  const chosen = select.value;
  const ids = [...state.robots.keys()].sort(naturalOrder);
  select.replaceChildren(new Option("any (fleet assigns)", ""), ...ids.map((id) => new Option(id, id)));
  select.value = ids.includes(chosen) ? chosen : "";
}

function renderRobots() {
  const body = $("robots-body");
  if (dirty.robotSet) {
    for (const [id, row] of robotRows) {
      if (!state.robots.has(id)) {
        row.remove();
        robotRows.delete(id);
      }
    }
    const ids = [...state.robots.keys()].sort(naturalOrder);
    for (const id of ids) {
      let row = robotRows.get(id);
      if (!row) {
        row = document.createElement("tr");
        row.dataset.robotId = id;
        row.append(...Array.from({ length: 5 }, () => document.createElement("td")));
        row.cells[0].className = "mono";
        row.cells[3].className = "mono num";
        row.cells[4].className = "mono";
        row.addEventListener("click", () => selectRobot(id));
        robotRows.set(id, row);
      }
      body.append(row); // (re)appending in order sorts the table
    }
    renderRobotSelect();
    dirty.robotSet = false;
  }
  const counts = {};
  for (const robot of state.robots.values()) {
    counts[robot.status] = (counts[robot.status] ?? 0) + 1;
    const row = robotRows.get(robot.id);
    if (!row) continue;
    row.dataset.status = robot.status;
    row.classList.toggle("selected", robot.id === state.highlight);
    const mode = escapeHtml(robot.status);
    const why = robot.detail ? `<div class="reason" title="${escapeHtml(robot.detail)}">${escapeHtml(robot.detail)}</div>` : "";
    setCell(row.cells[1], `<span class="badge mode-${mode}">${mode}</span>${why}`);
    setCell(
      row.cells[0],
      `${escapeHtml(robot.id)}${profileLine(robot)}<div class="robot-control">${robotButtons(robot)}</div>`,
    );
    setCell(row.cells[2], lawBadge(robot.law));
    setCell(row.cells[3], formatPose(robot.pose));
    setCell(row.cells[4], robot.task_id ? escapeHtml(shortId(robot.task_id)) : "—");
  }
  $("robot-count").textContent = String(state.robots.size);
  $("robots-empty").hidden = state.robots.size > 0;
  renderSummary(counts);
  dirty.robotTable = false;
}

/** What the robot said it is (README "Robots describe themselves"), or that the fleet plans
 * it with the host's own profile. */
function profileLine(robot) {
  if (!robot.described) return `<div class="reason">host profile (not described)</div>`;
  const parts = [];
  if (robot.model) parts.push(escapeHtml(robot.model));
  parts.push(`r ${Number(robot.radius).toFixed(2)} m`);
  if (robot.max_speed != null) parts.push(`${Number(robot.max_speed).toFixed(2)} m/s`);
  if (!robot.may_reverse) parts.push("no reverse: not assigned");
  return `<div class="reason">${parts.join(" · ")}</div>`;
}

function robotButtons(robot) {
  const id = escapeHtml(robot.id);
  const paused = robot.status === "paused";
  const stopped = robot.status === "estop";
  const button = (action, label, symbol, kind = "") =>
    `<button type="button" class="btn btn-small btn-icon ${kind}" data-action="${action}" ` +
    `data-robot="${id}" title="${label} ${id}" aria-label="${label} ${id}">${symbol}</button>`;
  const hold = paused ? button("resume", "Resume", "▶") : button("pause", "Pause", "❚❚");
  const stop = stopped
    ? button("release", "Release the e-stop of", "⟲", "btn-release")
    : button("estop", "Emergency stop", "■", "btn-danger");
  return hold + stop;
}

$("robots-body").addEventListener("click", (event) => {
  const button = event.target.closest("button[data-action]");
  if (!button) return;
  event.stopPropagation(); // not a row selection
  sendControl(button.dataset.action, button.dataset.robot);
});

async function sendControl(action, robotId = null) {
  try {
    const sent = await api.control(action, robotId, currentToken());
    const whom = sent.robot_id ? `robot ${sent.robot_id}` : "every robot";
    showMessage("operator-message", `${action} sent to ${whom}.`, action === "estop" ? "error" : "ok");
  } catch (err) {
    if (err instanceof ApiError && err.status === 401) {
      showMessage("operator-message", "The API needs a token: enter it at the top right.", "error");
      $("token").focus();
    } else {
      showMessage("operator-message", err instanceof ApiError ? err.message : "The server is unreachable.", "error");
    }
  }
  await refreshOperator();
}

$("estop").addEventListener("click", () => sendControl("estop"));
$("estop-release").addEventListener("click", () => sendControl("release"));
$("fleet-pause").addEventListener("click", () => sendControl("pause"));
$("fleet-resume").addEventListener("click", () => sendControl("resume"));

function renderOperator() {
  const stopped = [...state.robots.values()].filter((r) => r.status === "estop").map((r) => r.id);
  const latched = state.control.fleet.estop || stopped.length > 0;
  $("estop-banner").hidden = !latched;
  $("estop-release").hidden = !latched;
  document.body.classList.toggle("estopped", latched);
  $("estop-banner-text").textContent = stopped.length
    ? `${stopped.length} robot${stopped.length === 1 ? "" : "s"} e-stopped (${stopped.sort(naturalOrder).join(", ")})`
    : "the fleet's e-stop is latched";
  dirty.operator = false;
}

function allFaults() {
  const faults = [];
  for (const robot of state.robots.values()) {
    for (const error of robot.errors ?? []) faults.push({ robot: robot.id, ...error });
  }
  return faults.sort(
    (a, b) => LEVEL_ORDER[a.level] - LEVEL_ORDER[b.level] || a.since - b.since || naturalOrder(a.robot, b.robot),
  );
}

function renderFaults() {
  const faults = allFaults();
  $("faults").replaceChildren(
    ...faults.map((f) => {
      const li = document.createElement("li");
      li.className = `fault fault-${f.level}`;
      li.dataset.robot = f.robot;
      li.dataset.code = f.code;
      const since = new Date(f.since * 1000).toLocaleTimeString();
      li.innerHTML =
        `<span class="badge level-${escapeHtml(f.level)}">${escapeHtml(f.level)}</span>` +
        `<span class="mono">${escapeHtml(f.robot)}</span> <span class="mono fault-code">${escapeHtml(f.code)}</span>` +
        `<span class="fault-message">${escapeHtml(f.message)}</span><span class="fault-since">since ${since}</span>`;
      return li;
    }),
  );
  $("fault-count").textContent = String(faults.length);
  $("faults-empty").hidden = faults.length > 0;
  dirty.faults = false;
}

function renderSummary(counts) {
  const active = [...state.tasks.values()].filter((t) => ACTIVE.has(t.status)).length;
  const parts = Object.keys(MODE_COLORS)
    .filter((mode) => counts[mode])
    .map((mode) => `<span class="chip"><i style="background:${MODE_COLORS[mode]}"></i>${counts[mode]} ${mode}</span>`);
  const html =
    `<span class="chip chip-strong">${state.robots.size} robots</span>${parts.join("")}` +
    `<span class="chip chip-strong">${active} active tasks</span>`;
  const el = $("summary");
  if (el.innerHTML !== html) el.innerHTML = html;
}

function selectRobot(id) {
  state.highlight = state.highlight === id ? null : id;
  $("goal-robot").value = state.highlight ?? "";
  dirty.map = true;
  dirty.robotTable = true;
}

const taskRows = new Map();

function taskVisible(task) {
  const filter = $("task-filter").value;
  if (filter === "active") return ACTIVE.has(task.status);
  if (filter === "finished") return !ACTIVE.has(task.status);
  return true;
}

function renderTasks() {
  const body = $("tasks-body");
  for (const id of dirty.tasks) {
    const task = state.tasks.get(id);
    if (!task) continue;
    let row = taskRows.get(id);
    if (!row) {
      row = document.createElement("tr");
      row.dataset.taskId = id;
      row.append(...Array.from({ length: 5 }, () => document.createElement("td")));
      row.cells[1].className = "mono";
      row.cells[1].textContent = shortId(id);
      row.cells[1].title = id;
      row.cells[2].className = "mono";
      row.cells[4].className = "mono num";
      row.addEventListener("click", () => openTask(id));
      taskRows.set(id, row);
    }
    row.dataset.status = task.status;
    const reason = task.reason
      ? `<div class="reason" title="${escapeHtml(task.reason)}">${escapeHtml(task.reason)}</div>`
      : "";
    const status = escapeHtml(task.status);
    setCell(row.cells[0], `<span class="badge status-${status}">${status}</span>${reason}`);
    const robot = task.robot_id ?? (task.requested_robot_id ? `${task.requested_robot_id}?` : "any");
    setCell(row.cells[2], escapeHtml(robot));
    const direction = task.direction === "auto" ? "" : ' <span class="pinned" title="direction fixed by the request">●</span>';
    setCell(row.cells[3], lawBadge(task.law) + direction);
    setCell(row.cells[4], formatPose(task.goal));
    row.hidden = !taskVisible(task);
  }
  if (dirty.taskOrder) {
    const ordered = [...state.tasks.values()].sort((a, b) => b.created_at - a.created_at || (a.id < b.id ? 1 : -1));
    body.append(...ordered.map((t) => taskRows.get(t.id)).filter(Boolean));
    dirty.taskOrder = false;
  }
  dirty.tasks.clear();
  $("task-count").textContent = String(state.tasks.size);
  $("tasks-empty").hidden = state.tasks.size > 0;
  if (dialogTaskId) renderDialogFacts();
}

$("task-filter").addEventListener("change", () => {
  for (const [id, row] of taskRows) row.hidden = !taskVisible(state.tasks.get(id));
});

function escapeHtml(text) {
  return text.replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

// --- task dialog: facts, plot, cancel ---------------------------------------------

let dialogTaskId = null;

function renderDialogFacts() {
  const task = state.tasks.get(dialogTaskId);
  if (!task) return;
  const facts = [
    ["task", task.id],
    ["status", task.status],
    ["robot", task.robot_id ?? "not assigned"],
    ["requested", `${task.requested_robot_id ?? "any robot"}, direction ${task.direction}`],
    ["law", task.law ? `${task.law} · ${EQUATION[task.law]}` : "not chosen yet"],
    ["goal", formatPose(task.goal)],
    ["created", new Date(task.created_at * 1000).toLocaleString()],
    ["attempts", String(task.attempts)],
  ];
  if (task.route?.length) {
    facts.push(["route", task.route.map((p) => `(${p.x.toFixed(1)}, ${p.y.toFixed(1)})`).join(" → ")]);
  }
  if (task.reason) facts.push(["reason", task.reason]);
  const dl = $("dialog-facts");
  dl.replaceChildren(
    ...facts.flatMap(([k, v]) => {
      const dt = document.createElement("dt");
      dt.textContent = k;
      const dd = document.createElement("dd");
      dd.textContent = v;
      return [dt, dd];
    }),
  );
  $("dialog-title").textContent = `Task ${shortId(task.id)}`;
  $("dialog-cancel").hidden = !ACTIVE.has(task.status);
}

async function loadPlot() {
  const task = state.tasks.get(dialogTaskId);
  const img = $("dialog-plot");
  // No path is recorded before the robot reports the task (queued, or assigned and not
  // yet acknowledged): asking for the plot then would only fetch a 409.
  if (!task?.robot_id || task.status === "assigned") {
    img.removeAttribute("src");
    img.hidden = true;
    showMessage("dialog-message", "No plot until a robot drives the task.");
    return;
  }
  img.hidden = false;
  showMessage("dialog-message", "");
  img.src = api.plotUrl(task.id);
}

$("dialog-plot").addEventListener("error", () => {
  $("dialog-plot").hidden = true;
  showMessage("dialog-message", "No recorded path for this task (yet).");
});

async function loadHistory() {
  const id = dialogTaskId;
  const body = $("dialog-history-body");
  try {
    const events = await api.taskEvents(id);
    if (id !== dialogTaskId) return; // another task was opened meanwhile
    body.replaceChildren(
      ...events.map((e) => {
        const row = document.createElement("tr");
        const cells = [
          new Date(e.at * 1000).toLocaleTimeString(),
          e.event,
          e.status,
          e.robot_id ?? "—",
          e.law ?? "—",
          String(e.revision),
          String(e.attempts),
          e.reason ?? "",
        ];
        for (const text of cells) {
          const td = document.createElement("td");
          td.textContent = text;
          row.append(td);
        }
        row.dataset.event = e.event;
        return row;
      }),
    );
  } catch (err) {
    body.replaceChildren();
    showMessage("dialog-message", err instanceof ApiError ? err.message : "The server is unreachable.", "error");
  }
}

function openTask(id) {
  dialogTaskId = id;
  renderDialogFacts();
  loadPlot();
  loadHistory();
  $("task-dialog").showModal();
}

$("task-dialog").addEventListener("close", () => {
  dialogTaskId = null;
});
$("dialog-refresh").addEventListener("click", () => {
  loadPlot();
  loadHistory();
});
$("dialog-cancel").addEventListener("click", async () => {
  try {
    applyTask(await api.cancelTask(dialogTaskId, currentToken()));
    showMessage("dialog-message", "Cancelled.", "ok");
  } catch (err) {
    showMessage("dialog-message", err instanceof ApiError ? err.message : "The server is unreachable.", "error");
  }
});

// --- legend and options --------------------------------------------------------------

function renderLegend() {
  $("legend-modes").innerHTML = Object.entries(MODE_COLORS)
    .map(([mode, color]) => `<li><span class="sym sym-tri" style="--c:${color}"></span>${mode}</li>`)
    .join("");
  const laws = [
    ["ccw", `↺ ccw · ${EQUATION.ccw}`],
    ["cw", `↻ cw · ${EQUATION.cw}`],
    ["none", "no law yet"],
  ];
  $("legend-laws").innerHTML = laws
    .map(([law, text]) => `<li><span class="sym sym-line" style="--c:${LAW_COLORS[law]}"></span>${text}</li>`)
    .join("");
}

for (const option of ["trails", "labels", "peers"]) {
  const box = $(`opt-${option}`);
  state.options[option] = box.checked;
  box.addEventListener("change", () => {
    state.options[option] = box.checked;
    dirty.map = true;
  });
}

// --- the frame loop ------------------------------------------------------------------

let lastFrame = performance.now();
let lastRobotTable = 0;
let lastRate = { at: performance.now(), events: 0 };

function frame(now) {
  const started = performance.now();
  const dt = Math.min(0.1, (now - lastFrame) / 1000);
  lastFrame = now;
  drainPending();
  if (map.resize()) dirty.map = true;
  const moving = smooth(dt);
  if (dirty.map || moving) {
    drawMap();
    state.frames += 1;
    dirty.map = false;
  }
  if (dirty.tasks.size || dirty.taskOrder) {
    renderTasks();
    dirty.robotTable = true; // the summary counts active tasks
  }
  if ((dirty.robotTable || dirty.robotSet) && now - lastRobotTable >= ROBOT_TABLE_MS) {
    renderRobots();
    if (dirty.faults) renderFaults();
    lastRobotTable = now;
  }
  if (dirty.operator) renderOperator();
  if (now - lastRate.at >= 1000) {
    const rate = ((state.events - lastRate.events) * 1000) / (now - lastRate.at);
    $("rate").textContent = `${rate.toFixed(0)} ev/s`;
    lastRate = { at: now, events: state.events };
  }
  const work = performance.now() - started;
  state.workMs = 0.95 * state.workMs + 0.05 * work; // smoothed script time per frame
  state.workMaxMs = Math.max(state.workMaxMs, work);
  requestAnimationFrame(frame);
}

// For operators' scripts and the browser tests: a read-only view of what the page shows.
window.__parkfleet = {
  get connection() {
    return state.connection;
  },
  get frames() {
    return state.frames;
  },
  get loads() {
    return state.loads;
  },
  /** Script time per animation frame [ms]: smoothed mean and maximum since load. */
  get work() {
    return { mean: state.workMs, max: state.workMaxMs };
  },
  robots: () =>
    [...state.robots.values()].map((r) => ({
      id: r.id,
      status: r.status,
      detail: r.detail,
      errors: r.errors,
      x: r.pose.x,
      y: r.pose.y,
      theta: r.pose.theta,
      law: r.law,
      task_id: r.task_id,
      radius: r.radius,
      described: r.described,
      trail: r.trail.length,
    })),
  tasks: () => [...state.tasks.values()].map((t) => ({ ...t })),
  /** The operator's holds as last fetched (GET /control). */
  get control() {
    return state.control;
  },
  bays: () => state.bays.map((b) => ({ ...b })),
  zones: () => state.zones.map((z) => ({ ...z })),
  faults: () => allFaults(),
  /** What the map drew last frame: keep-out zones, bays, single-robot zones (and how many
   * held), wall segments and routes. */
  get drawn() {
    return { ...map.drawn };
  },
  /** Page (CSS px) coordinates of a world point [m], e.g. to click on it. */
  worldToPage(x, y) {
    const rect = canvas.getBoundingClientRect();
    const [px, py] = map.toCanvas(x, y);
    return [rect.left + px, rect.top + py];
  },
};

renderLegend();
map.setLegendWidth($("legend").offsetWidth + 16);
map.resize();
stream.start();
pollObstacles();
pollService();
pollOperator();
requestAnimationFrame(frame);
