// REST and Server-Sent Events client of the parkfleet API.
//
// URLs are relative to the page, so the console also works behind a reverse proxy that
// serves the API under a path prefix.

const TOKEN_KEY = "parkfleet.apiToken";

/** The API token kept in this browser (localStorage), or "" when none. */
export function loadToken() {
  try {
    return localStorage.getItem(TOKEN_KEY) ?? "";
  } catch {
    return ""; // storage disabled: the token lives only in the input field
  }
}

export function saveToken(token) {
  try {
    if (token) localStorage.setItem(TOKEN_KEY, token);
    else localStorage.removeItem(TOKEN_KEY);
  } catch {
    /* storage disabled */
  }
}

/** An error response of the API: `status` and the server's `detail` text. */
export class ApiError extends Error {
  constructor(status, detail) {
    super(detail);
    this.status = status;
  }
}

async function request(method, path, { body, token, headers = {} } = {}) {
  const init = { method, headers: { Accept: "application/json", ...headers } };
  if (token) init.headers.Authorization = `Bearer ${token}`;
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const response = await fetch(path, init);
  const text = await response.text();
  let data = null;
  try {
    data = text ? JSON.parse(text) : null;
  } catch {
    data = null;
  }
  if (!response.ok) {
    const detail = data && typeof data.detail === "string" ? data.detail : `HTTP ${response.status}`;
    throw new ApiError(response.status, detail);
  }
  return data;
}

/** A key that makes a repeated submission (double click, retry) return the same task. */
export function idempotencyKey() {
  if (globalThis.crypto?.randomUUID) return crypto.randomUUID(); // secure contexts only
  return `${Date.now().toString(36)}-${Math.random().toString(36).slice(2)}`;
}

export const api = {
  config: () => request("GET", "config"),
  robots: () => request("GET", "robots"),
  tasks: (limit) => request("GET", `tasks?order=newest&limit=${limit}`), // the newest `limit`
  obstacles: () => request("GET", "obstacles"),
  health: () => request("GET", "healthz"),
  submitTask: (body, token, key) =>
    request("POST", "tasks", { body, token, headers: { "Idempotency-Key": key } }),
  cancelTask: (id, token) => request("POST", `tasks/${encodeURIComponent(id)}/cancel`, { token }),
  plotUrl: (id) => `tasks/${encodeURIComponent(id)}/plot.png?t=${Date.now()}`,
  taskEvents: (id) => request("GET", `tasks/${encodeURIComponent(id)}/events`),
  /** pause | resume | estop | release, for the fleet (robotId null) or one robot. */
  control: (action, robotId, token) =>
    request("POST", `control/${action}`, { body: robotId ? { robot_id: robotId } : {}, token }),
  controlState: () => request("GET", "control"),
  site: () => request("GET", "site"),
  bays: () => request("GET", "bays"),
  zones: () => request("GET", "zones"),
};

/**
 * The live event stream, reconnecting for ever.
 *
 * EventSource retries by itself after a dropped connection (the server asks for 2 s), but
 * gives up for good when a reconnection attempt gets an error status or a wrong content
 * type (e.g. while the server restarts behind a proxy); then we open a new one with
 * backoff. `onOpen` runs on every (re)connection so the caller can re-fetch the state it
 * may have missed.
 */
export class EventStream {
  constructor(url, { onOpen, onState, onEvent }) {
    this.url = url;
    this.onOpen = onOpen;
    this.onState = onState;
    this.onEvent = onEvent;
    this.source = null;
    this.retryMs = 1000;
    this.timer = null;
  }

  start() {
    this.onState("connecting");
    const source = new EventSource(this.url);
    this.source = source;
    source.onopen = () => {
      this.retryMs = 1000;
      this.onState("live");
      this.onOpen();
    };
    source.onerror = () => {
      if (source.readyState === EventSource.CLOSED) {
        this.onState("offline");
        source.close();
        clearTimeout(this.timer);
        this.timer = setTimeout(() => this.start(), this.retryMs);
        this.retryMs = Math.min(this.retryMs * 2, 15000);
      } else {
        this.onState("reconnecting"); // EventSource retries by itself
      }
    };
    for (const type of ["robot", "task"]) {
      source.addEventListener(type, (message) => {
        let data;
        try {
          data = JSON.parse(message.data);
        } catch {
          return; // a malformed frame is dropped, never thrown into the UI
        }
        this.onEvent(type, data);
      });
    }
    // The server drops a client that fell too far behind; EventSource then reconnects and
    // the snapshot it sends first brings the map up to date.
    source.addEventListener("overflow", () => this.onState("reconnecting"));
  }
}
