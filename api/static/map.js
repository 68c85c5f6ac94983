// Canvas 2D map of the yard: axes in metres, obstacles with their bodies and influence zones, goals,
// trails, and robots drawn as oriented triangles as in the paper's figures.
//
// World frame: x to the right, y up, theta counter-clockwise from +x [rad]. The canvas is
// sized in CSS pixels times devicePixelRatio; all drawing below is in CSS pixels.

export const MODE_COLORS = {
  idle: "#94a3b8",
  driving: "#3b82f6",
  avoiding: "#f59e0b",
  arrived: "#22c55e",
  holding: "#a855f7",
  waiting: "#14b8a6",
  paused: "#eab308",
  estop: "#dc2626",
  lost: "#ef4444",
};

export const LAW_COLORS = { ccw: "#22d3ee", cw: "#f472b6", none: "#64748b" };

const COLORS = {
  outside: "#0b1016",
  yard: "#111a24",
  gridMinor: "rgba(148, 163, 184, 0.07)",
  gridMajor: "rgba(148, 163, 184, 0.17)",
  axis: "rgba(148, 163, 184, 0.55)",
  yardEdge: "rgba(148, 163, 184, 0.6)",
  tick: "#8b99ab",
  label: "#d5dde8",
  obstacleZone: "rgba(239, 68, 68, 0.10)",
  obstacleEdge: "rgba(248, 113, 113, 0.65)",
  obstacleCore: "#f87171",
  draft: "#fde047",
  keepOut: "rgba(250, 204, 21, 0.10)",
  keepOutEdge: "rgba(250, 204, 21, 0.75)",
  lane: "rgba(56, 189, 248, 0.55)",
  zone: "rgba(167, 139, 250, 0.08)",
  zoneHeld: "rgba(192, 132, 252, 0.22)",
  zoneEdge: "rgba(167, 139, 250, 0.85)",
};

/** Outline colour of a bay by state (free / reserved by a task / occupied by a robot). */
export const BAY_COLORS = { free: "#4ade80", reserved: "#f59e0b", occupied: "#60a5fa" };

const MARGIN = { left: 52, right: 16, top: 14, bottom: 40 };
const TICK_STEPS = [0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500];
const FONT = "12px ui-sans-serif, system-ui, -apple-system, 'Segoe UI', Roboto, sans-serif";
const FONT_SMALL = "11px ui-monospace, 'SFMono-Regular', Menlo, Consolas, monospace";

export function lawColor(law) {
  return LAW_COLORS[law] ?? LAW_COLORS.none;
}

/** Triangle vertices (canvas px) of a pose: nose along theta, as the paper's figures. */
function trianglePath(ctx, cx, cy, theta, size) {
  const c = Math.cos(theta);
  const s = -Math.sin(theta); // canvas y points down
  const pts = [
    [size, 0],
    [-0.6 * size, 0.5 * size],
    [-0.6 * size, -0.5 * size],
  ];
  ctx.beginPath();
  pts.forEach(([bx, by], i) => {
    const x = cx + bx * c - by * s;
    const y = cy + bx * s + by * c;
    if (i === 0) ctx.moveTo(x, y);
    else ctx.lineTo(x, y);
  });
  ctx.closePath();
}

/**
 * The law as the way the robot turns: an arc behind it with an arrowhead, counter-clockwise
 * for ccw (Eq. 17, omega >= 0) and clockwise for cw (Eq. 20, omega <= 0), in the law's
 * colour. World angles phi; canvas angles are -phi because canvas y points down.
 */
/**
 * The via-points of `route` a robot at `pose` still has to pass: those after the one it is
 * nearest to the leg of (the robot reports its pose, not its leg).
 */
function remainingVia(route, pose) {
  if (route.length === 0) return [];
  let best = 0;
  let bestDistance = Infinity;
  let from = route[0];
  for (let k = 0; k < route.length; k += 1) {
    // distance from the robot to the leg arriving at via-point k (the first: the point)
    const to = route[k];
    const dx = to.x - from.x;
    const dy = to.y - from.y;
    const length = dx * dx + dy * dy;
    const t = length > 0 ? Math.max(0, Math.min(1, ((pose.x - from.x) * dx + (pose.y - from.y) * dy) / length)) : 0;
    const d = Math.hypot(from.x + t * dx - pose.x, from.y + t * dy - pose.y);
    if (d < bestDistance) {
      bestDistance = d;
      best = k;
    }
    from = to;
  }
  return route.slice(best);
}

function drawTurnArrow(ctx, cx, cy, theta, r, law) {
  const ccw = law === "ccw";
  const from = theta + (ccw ? 2.2 : 4.1); // the arc spans the robot's back
  const to = theta + (ccw ? 4.1 : 2.2);
  ctx.strokeStyle = lawColor(law);
  ctx.fillStyle = ctx.strokeStyle;
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.arc(cx, cy, r, -from, -to, ccw);
  ctx.stroke();
  // Arrowhead at the end, along the direction of travel round the circle.
  const ex = cx + r * Math.cos(to);
  const ey = cy - r * Math.sin(to);
  const sign = ccw ? 1 : -1;
  const tx = -sign * Math.sin(to); // world tangent
  const ty = sign * Math.cos(to);
  const [ux, uy] = [tx, -ty]; // canvas tangent
  const [nx, ny] = [-uy, ux];
  const head = 5;
  ctx.beginPath();
  ctx.moveTo(ex + ux * head, ey + uy * head);
  ctx.lineTo(ex - ux * head * 0.4 + nx * head * 0.7, ey - uy * head * 0.4 + ny * head * 0.7);
  ctx.lineTo(ex - ux * head * 0.4 - nx * head * 0.7, ey - uy * head * 0.4 - ny * head * 0.7);
  ctx.closePath();
  ctx.fill();
}

function formatTick(value, step) {
  const digits = step >= 1 ? 0 : step >= 0.1 ? 1 : 2;
  const text = value.toFixed(digits);
  return text === "-0" ? "0" : text;
}

export class YardMap {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.yard = [-10, 10, -10, 10];
    this.width = 0; // CSS px
    this.height = 0;
    this.scale = 1; // px per metre
    this.ox = 0; // canvas px of world x = 0
    this.oy = 0; // canvas px of world y = 0
  }

  setYard(yard) {
    this.yard = yard;
    this.layout();
  }

  /** Fit the canvas to its box (call on resize); returns true when the size changed. */
  resize() {
    const rect = this.canvas.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(rect.width));
    const h = Math.max(1, Math.round(rect.height));
    if (w === this.width && h === this.height && this.dpr === dpr) return false;
    this.width = w;
    this.height = h;
    this.dpr = dpr;
    this.canvas.width = Math.round(w * dpr);
    this.canvas.height = Math.round(h * dpr);
    this.layout();
    return true;
  }

  /** Width [px] of the legend overlaid at the top right: kept clear of the yard when that
   * costs the yard little (a wide window), overlaid otherwise. */
  setLegendWidth(width) {
    this.legendWidth = width;
    this.layout();
  }

  layout() {
    const [xmin, xmax, ymin, ymax] = this.yard;
    let w = this.width - MARGIN.left - MARGIN.right;
    const h = this.height - MARGIN.top - MARGIN.bottom;
    const fit = (width) => Math.max(1e-6, Math.min(width / (xmax - xmin), h / (ymax - ymin)));
    const reserve = this.legendWidth ?? 0;
    if (reserve > 0 && fit(w - reserve) >= 0.92 * fit(w)) w -= reserve;
    this.scale = fit(w);
    const usedW = (xmax - xmin) * this.scale;
    const usedH = (ymax - ymin) * this.scale;
    const left = MARGIN.left + (w - usedW) / 2;
    const top = MARGIN.top + (h - usedH) / 2;
    this.ox = left - xmin * this.scale;
    this.oy = top + ymax * this.scale;
  }

  toCanvas(x, y) {
    return [this.ox + x * this.scale, this.oy - y * this.scale];
  }

  toWorld(px, py) {
    return [(px - this.ox) / this.scale, (this.oy - py) / this.scale];
  }

  insideYard(x, y) {
    const [xmin, xmax, ymin, ymax] = this.yard;
    return x >= xmin && x <= xmax && y >= ymin && y <= ymax;
  }

  /** Draw one frame. `scene` is built by the app each frame (see app.js). */
  draw(scene) {
    const ctx = this.ctx;
    ctx.setTransform(this.dpr, 0, 0, this.dpr, 0, 0);
    ctx.fillStyle = COLORS.outside;
    ctx.fillRect(0, 0, this.width, this.height);
    this.drawYard();
    this.drawSite(scene.site, scene.bays ?? []);
    this.drawZones(scene.zones ?? []);
    this.drawObstacles(scene.obstacles);
    if (scene.options.trails) this.drawTrails(scene.robots);
    this.drawGoals(scene.goals, scene.robots);
    this.drawPeerZones(scene.robots, scene.peerRadius, scene.options.peers);
    this.drawRobots(scene.robots, scene.robotRadius, scene.options.labels, scene.highlight);
    if (scene.draft) this.drawDraft(scene.draft);
  }

  drawYard() {
    const ctx = this.ctx;
    const [xmin, xmax, ymin, ymax] = this.yard;
    const [x0, y0] = this.toCanvas(xmin, ymax);
    const [x1, y1] = this.toCanvas(xmax, ymin);
    ctx.fillStyle = COLORS.yard;
    ctx.fillRect(x0, y0, x1 - x0, y1 - y0);

    const major = TICK_STEPS.find((s) => s * this.scale >= 46) ?? TICK_STEPS.at(-1);
    const minor = major / (String(major).startsWith("2") ? 4 : 5);
    ctx.lineWidth = 1;
    const lines = (step, color) => {
      if (step * this.scale < 7) return;
      ctx.strokeStyle = color;
      ctx.beginPath();
      for (let x = Math.ceil(xmin / step) * step; x <= xmax + 1e-9; x += step) {
        const px = Math.round(this.toCanvas(x, 0)[0]) + 0.5;
        ctx.moveTo(px, y0);
        ctx.lineTo(px, y1);
      }
      for (let y = Math.ceil(ymin / step) * step; y <= ymax + 1e-9; y += step) {
        const py = Math.round(this.toCanvas(0, y)[1]) + 0.5;
        ctx.moveTo(x0, py);
        ctx.lineTo(x1, py);
      }
      ctx.stroke();
    };
    lines(minor, COLORS.gridMinor);
    lines(major, COLORS.gridMajor);

    // Axes through the origin, when it is in the yard.
    ctx.strokeStyle = COLORS.axis;
    ctx.beginPath();
    if (xmin <= 0 && xmax >= 0) {
      const px = Math.round(this.ox) + 0.5;
      ctx.moveTo(px, y0);
      ctx.lineTo(px, y1);
    }
    if (ymin <= 0 && ymax >= 0) {
      const py = Math.round(this.oy) + 0.5;
      ctx.moveTo(x0, py);
      ctx.lineTo(x1, py);
    }
    ctx.stroke();

    ctx.strokeStyle = COLORS.yardEdge;
    ctx.strokeRect(Math.round(x0) + 0.5, Math.round(y0) + 0.5, Math.round(x1 - x0), Math.round(y1 - y0));

    // Tick labels along the bottom and left edges; axis titles.
    ctx.font = FONT_SMALL;
    ctx.fillStyle = COLORS.tick;
    ctx.textAlign = "center";
    ctx.textBaseline = "top";
    for (let x = Math.ceil(xmin / major) * major; x <= xmax + 1e-9; x += major) {
      const px = this.toCanvas(x, 0)[0];
      ctx.fillRect(Math.round(px), y1, 1, 4);
      ctx.fillText(formatTick(x, major), px, y1 + 6);
    }
    ctx.textAlign = "right";
    ctx.textBaseline = "middle";
    for (let y = Math.ceil(ymin / major) * major; y <= ymax + 1e-9; y += major) {
      const py = this.toCanvas(0, y)[1];
      ctx.fillRect(x0 - 4, Math.round(py), 4, 1);
      ctx.fillText(formatTick(y, major), x0 - 7, py);
    }
    ctx.font = FONT;
    ctx.fillStyle = COLORS.label;
    ctx.textAlign = "center";
    ctx.textBaseline = "bottom";
    ctx.fillText("x [m]", (x0 + x1) / 2, this.height - 4);
    ctx.save();
    ctx.translate(14, (y0 + y1) / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textBaseline = "middle";
    ctx.fillText("y [m]", 0, 0);
    ctx.restore();
  }

  /** Keep-out zones (hatched, named) and bays (outlined by state, named). */
  drawSite(site, bays) {
    this.drawn = { zones: 0, bays: 0 };
    if (!site) return;
    const ctx = this.ctx;
    ctx.font = FONT_SMALL;
    for (const zone of site.keep_out) {
      ctx.beginPath();
      let label;
      if (zone.circle) {
        const [cx, cy] = this.toCanvas(zone.circle.x, zone.circle.y);
        ctx.arc(cx, cy, zone.circle.radius * this.scale, 0, 2 * Math.PI);
        label = [cx, cy];
      } else {
        const r = zone.rect;
        const points = zone.polygon ?? [[r.xmin, r.ymin], [r.xmax, r.ymin], [r.xmax, r.ymax], [r.xmin, r.ymax]];
        points.forEach(([x, y], i) => {
          const [px, py] = this.toCanvas(x, y);
          if (i === 0) ctx.moveTo(px, py);
          else ctx.lineTo(px, py);
        });
        ctx.closePath();
        const mx = points.reduce((s, p) => s + p[0], 0) / points.length;
        const my = points.reduce((s, p) => s + p[1], 0) / points.length;
        label = this.toCanvas(mx, my);
      }
      ctx.fillStyle = COLORS.keepOut;
      ctx.fill();
      ctx.setLineDash([3, 3]);
      ctx.strokeStyle = COLORS.keepOutEdge;
      ctx.lineWidth = 1.2;
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = COLORS.keepOutEdge;
      ctx.textAlign = "center";
      ctx.textBaseline = "middle";
      ctx.fillText(zone.name, label[0], label[1]);
      this.drawn.zones += 1;
    }
    this.drawLanes(site.lanes ?? []);
    const states = new Map(bays.map((b) => [b.name, b.status]));
    for (const bay of site.bays) {
      const [cx, cy] = this.toCanvas(bay.pose.x, bay.pose.y);
      const half = Math.max(6, 0.35 * this.scale); // a 0.7 m square
      ctx.save();
      ctx.translate(cx, cy);
      ctx.rotate(-bay.pose.theta); // canvas y points down
      ctx.strokeStyle = BAY_COLORS[states.get(bay.name) ?? "free"];
      ctx.lineWidth = states.get(bay.name) && states.get(bay.name) !== "free" ? 2.4 : 1.2;
      ctx.strokeRect(-half, -half, 2 * half, 2 * half);
      ctx.beginPath(); // the nose: which way the robot parks
      ctx.moveTo(half, -half * 0.5);
      ctx.lineTo(half + half * 0.5, 0);
      ctx.lineTo(half, half * 0.5);
      ctx.stroke();
      ctx.restore();
      ctx.fillStyle = ctx.strokeStyle;
      ctx.textAlign = "center";
      ctx.textBaseline = "bottom";
      ctx.fillText(bay.name, cx, cy - half - 2);
      this.drawn.bays += 1;
    }
  }

  /** Lanes: dashed lines, an arrow on every leg of a one-way lane. */
  drawLanes(lanes) {
    this.drawn.lanes = 0;
    const ctx = this.ctx;
    ctx.save();
    ctx.strokeStyle = COLORS.lane;
    ctx.fillStyle = COLORS.lane;
    ctx.lineWidth = 1.5;
    for (const lane of lanes) {
      const points = lane.points.map(([x, y]) => this.toCanvas(x, y));
      ctx.setLineDash([8, 5]);
      ctx.beginPath();
      points.forEach(([px, py], i) => (i === 0 ? ctx.moveTo(px, py) : ctx.lineTo(px, py)));
      ctx.stroke();
      ctx.setLineDash([]);
      if (lane.one_way) {
        for (let i = 1; i < points.length; i++) {
          const [ax, ay] = points[i - 1];
          const [bx, by] = points[i];
          const angle = Math.atan2(by - ay, bx - ax);
          const [mx, my] = [(ax + bx) / 2, (ay + by) / 2];
          ctx.beginPath();
          ctx.moveTo(mx + 7 * Math.cos(angle), my + 7 * Math.sin(angle));
          ctx.lineTo(mx + 5 * Math.cos(angle + 2.5), my + 5 * Math.sin(angle + 2.5));
          ctx.lineTo(mx + 5 * Math.cos(angle - 2.5), my + 5 * Math.sin(angle - 2.5));
          ctx.closePath();
          ctx.fill();
        }
      }
      this.drawn.lanes += 1;
    }
    ctx.restore();
  }

  /** Single-robot zones: outlined, filled while held, named with the robots holding them. */
  drawZones(zones) {
    this.drawn.singleZones = 0;
    this.drawn.zonesHeld = 0;
    const ctx = this.ctx;
    ctx.font = FONT_SMALL;
    for (const zone of zones) {
      if (zone.polygon.length < 3) continue;
      ctx.beginPath();
      zone.polygon.forEach(([x, y], i) => {
        const [px, py] = this.toCanvas(x, y);
        if (i === 0) ctx.moveTo(px, py);
        else ctx.lineTo(px, py);
      });
      ctx.closePath();
      const held = zone.robot_ids.length > 0;
      ctx.fillStyle = held ? COLORS.zoneHeld : COLORS.zone;
      ctx.fill();
      ctx.setLineDash([6, 3]);
      ctx.strokeStyle = COLORS.zoneEdge;
      ctx.lineWidth = held ? 2 : 1.2;
      ctx.stroke();
      ctx.setLineDash([]);
      const mx = zone.polygon.reduce((s, p) => s + p[0], 0) / zone.polygon.length;
      const my = Math.max(...zone.polygon.map((p) => p[1]));
      const [lx, ly] = this.toCanvas(mx, my);
      ctx.fillStyle = COLORS.zoneEdge;
      ctx.textAlign = "center";
      ctx.textBaseline = "bottom";
      ctx.fillText(held ? `${zone.name}: ${zone.robot_ids.join(", ")}` : zone.name, lx, ly - 2);
      this.drawn.singleZones += 1;
      if (held) this.drawn.zonesHeld += 1;
    }
  }

  drawObstacles(obstacles) {
    const ctx = this.ctx;
    this.drawn.walls = 0;
    obstacles.forEach((o, i) => {
      if (o.end) {
        this.drawWall(o);
        return;
      }
      const [cx, cy] = this.toCanvas(o.x, o.y);
      const r = o.radius * this.scale;
      ctx.beginPath();
      ctx.arc(cx, cy, r, 0, 2 * Math.PI);
      ctx.fillStyle = COLORS.obstacleZone;
      ctx.fill();
      ctx.setLineDash([5, 4]);
      ctx.strokeStyle = COLORS.obstacleEdge;
      ctx.lineWidth = 1.2;
      ctx.stroke();
      ctx.setLineDash([]);
      // The obstacle's body (what robots keep their margin from), at least a visible dot.
      const body = Math.max(3, (o.body ?? 0) * this.scale);
      ctx.beginPath();
      ctx.arc(cx, cy, body, 0, 2 * Math.PI);
      ctx.fillStyle = COLORS.obstacleCore;
      ctx.fill();
      if (r > 18) {
        ctx.font = FONT_SMALL;
        ctx.fillStyle = COLORS.obstacleEdge;
        ctx.textAlign = "center";
        ctx.textBaseline = "top";
        ctx.fillText(`obstacle ${i}`, cx, cy + body + 3);
      }
    });
  }

  /** A wall segment: its influence band, then its body (a thick line with round ends). */
  drawWall(o) {
    const ctx = this.ctx;
    const [ax, ay] = this.toCanvas(o.x, o.y);
    const [bx, by] = this.toCanvas(o.end[0], o.end[1]);
    ctx.save();
    ctx.lineCap = "round";
    ctx.beginPath();
    ctx.moveTo(ax, ay);
    ctx.lineTo(bx, by);
    ctx.strokeStyle = COLORS.obstacleZone;
    ctx.lineWidth = 2 * o.radius * this.scale;
    ctx.stroke();
    ctx.strokeStyle = COLORS.obstacleCore;
    ctx.lineWidth = Math.max(3, 2 * (o.body ?? 0) * this.scale);
    ctx.stroke();
    ctx.restore();
    this.drawn.walls += 1;
  }

  drawTrails(robots) {
    const ctx = this.ctx;
    ctx.lineWidth = 1.6;
    ctx.lineJoin = "round";
    for (const robot of robots) {
      const trail = robot.trail;
      if (trail.length < 2) continue;
      ctx.strokeStyle = lawColor(robot.law);
      ctx.globalAlpha = robot.status === "lost" ? 0.25 : 0.55;
      ctx.beginPath();
      trail.forEachPoint((x, y, i) => {
        const [px, py] = this.toCanvas(x, y);
        if (i === 0) ctx.moveTo(px, py);
        else ctx.lineTo(px, py);
      });
      ctx.lineTo(...this.toCanvas(robot.display.x, robot.display.y));
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
  }

  robotSize(radius) {
    return Math.max(11, 1.4 * radius * this.scale);
  }

  drawGoals(goals, robots) {
    const ctx = this.ctx;
    const byId = new Map(robots.map((r) => [r.id, r]));
    this.drawn.routes = 0;
    for (const goal of goals) {
      const [gx, gy] = this.toCanvas(goal.x, goal.y);
      const color = lawColor(goal.law);
      const robot = goal.robotId ? byId.get(goal.robotId) : undefined;
      if (robot && robot.status !== "arrived") {
        // The way the robot was sent: through the via-points of its route, then the goal.
        const via = remainingVia(goal.route ?? [], robot.display);
        const [rx, ry] = this.toCanvas(robot.display.x, robot.display.y);
        ctx.strokeStyle = color;
        ctx.globalAlpha = via.length ? 0.7 : 0.35;
        ctx.setLineDash([2, 4]);
        ctx.lineWidth = via.length ? 1.5 : 1;
        ctx.beginPath();
        ctx.moveTo(rx, ry);
        for (const point of via) ctx.lineTo(...this.toCanvas(point.x, point.y));
        ctx.lineTo(gx, gy);
        ctx.stroke();
        for (const point of via) {
          const [vx, vy] = this.toCanvas(point.x, point.y);
          ctx.beginPath();
          ctx.arc(vx, vy, 2.5, 0, 2 * Math.PI);
          ctx.fillStyle = color;
          ctx.fill();
        }
        ctx.globalAlpha = 1;
        if (via.length) this.drawn.routes += 1;
      }
      ctx.setLineDash(goal.queued ? [3, 3] : []);
      ctx.lineWidth = 2;
      ctx.strokeStyle = color;
      trianglePath(ctx, gx, gy, goal.theta, this.robotSize(0.2) * 1.15);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.beginPath();
      ctx.arc(gx, gy, 2, 0, 2 * Math.PI);
      ctx.fillStyle = color;
      ctx.fill();
    }
  }

  drawPeerZones(robots, peerRadius, all) {
    const ctx = this.ctx;
    const r = peerRadius * this.scale;
    ctx.lineWidth = 1;
    ctx.setLineDash([4, 4]);
    for (const robot of robots) {
      if (!all && robot.status !== "avoiding") continue;
      const [cx, cy] = this.toCanvas(robot.display.x, robot.display.y);
      ctx.beginPath();
      ctx.arc(cx, cy, r, 0, 2 * Math.PI);
      ctx.strokeStyle = robot.status === "avoiding" ? "rgba(245, 158, 11, 0.6)" : "rgba(148, 163, 184, 0.28)";
      ctx.fillStyle = robot.status === "avoiding" ? "rgba(245, 158, 11, 0.06)" : "rgba(148, 163, 184, 0.03)";
      ctx.fill();
      ctx.stroke();
    }
    ctx.setLineDash([]);
  }

  drawRobots(robots, robotRadius, labels, highlight) {
    const ctx = this.ctx;
    for (const robot of robots) {
      const { x, y, theta } = robot.display;
      const [cx, cy] = this.toCanvas(x, y);
      const lost = robot.status === "lost";
      const fill = MODE_COLORS[robot.status] ?? MODE_COLORS.idle;
      const radius = robot.radius || robotRadius;
      // Body footprint.
      ctx.beginPath();
      ctx.arc(cx, cy, radius * this.scale, 0, 2 * Math.PI);
      ctx.fillStyle = fill;
      ctx.globalAlpha = 0.14;
      ctx.fill();
      ctx.globalAlpha = lost ? 0.55 : 1;
      if (robot.id === highlight) {
        ctx.beginPath();
        ctx.arc(cx, cy, this.robotSize(radius) + 6, 0, 2 * Math.PI);
        ctx.strokeStyle = "#fde047";
        ctx.lineWidth = 2;
        ctx.stroke();
      }
      const size = this.robotSize(radius);
      const steering = robot.status === "driving" || robot.status === "avoiding";
      if (robot.law && steering) drawTurnArrow(ctx, cx, cy, theta, size + 4, robot.law);
      trianglePath(ctx, cx, cy, theta, size);
      ctx.fillStyle = fill;
      ctx.fill();
      ctx.lineWidth = 1.5;
      ctx.strokeStyle = lost ? "#fca5a5" : "#0b1016";
      if (lost) ctx.setLineDash([3, 2]);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.globalAlpha = 1;
      if (labels) {
        ctx.font = FONT_SMALL;
        ctx.textAlign = "left";
        ctx.textBaseline = "middle";
        const text = robot.law ? `${robot.id} · ${robot.law}` : robot.id;
        const tx = cx + size + 4;
        const ty = cy - size * 0.9;
        ctx.lineWidth = 3;
        ctx.strokeStyle = "rgba(11, 16, 22, 0.85)";
        ctx.strokeText(text, tx, ty);
        ctx.fillStyle = lost ? "#fca5a5" : "#e2e8f0";
        ctx.fillText(text, tx, ty);
      }
    }
  }

  drawDraft(draft) {
    const ctx = this.ctx;
    const [cx, cy] = this.toCanvas(draft.x, draft.y);
    const size = this.robotSize(0.2) * 1.3;
    ctx.beginPath();
    ctx.arc(cx, cy, size + 5, 0, 2 * Math.PI);
    ctx.fillStyle = "rgba(253, 224, 71, 0.10)";
    ctx.fill();
    ctx.setLineDash([4, 3]);
    ctx.strokeStyle = COLORS.draft;
    ctx.lineWidth = 1;
    ctx.stroke();
    ctx.setLineDash([]);
    // Heading arrow.
    const len = size + 22;
    const ex = cx + len * Math.cos(draft.theta);
    const ey = cy - len * Math.sin(draft.theta);
    ctx.beginPath();
    ctx.moveTo(cx, cy);
    ctx.lineTo(ex, ey);
    ctx.lineWidth = 1.5;
    ctx.stroke();
    trianglePath(ctx, cx, cy, draft.theta, size);
    ctx.lineWidth = 2.5;
    ctx.strokeStyle = COLORS.draft;
    ctx.stroke();
    ctx.font = FONT_SMALL;
    ctx.fillStyle = COLORS.draft;
    ctx.textAlign = "left";
    ctx.textBaseline = "top";
    const deg = ((draft.theta * 180) / Math.PI).toFixed(0);
    ctx.fillText(`goal (${draft.x.toFixed(2)}, ${draft.y.toFixed(2)}) m, ${deg}°`, cx + size + 8, cy + 6);
  }
}
