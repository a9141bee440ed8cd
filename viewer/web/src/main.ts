// The viewer's page: the session list, a watched session as it ticks, and rollout files with a time scrubber.
// Everything it loads comes from the gateway that served it (scenestreamer-viewer); docs/viewer.md.
import "./style.css";
import { EGO_COLOUR, LIGHT_COLOURS, Renderer, Scene, TYPE_COLOURS, View } from "./draw";
import { Agent, Flag, MapFeature, RolloutResponse, ScenarioFile, SessionRow, TickMessage, Track } from "./types";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const TRAIL_TICKS = 10;
const LEAVING_TICKS = 4;

// --- state ---------------------------------------------------------------------------------------------------
const canvas = $<HTMLCanvasElement>("canvas");
const renderer = new Renderer(canvas);
const view: View = { cx: 0, cy: 0, scale: 4 };
let follow = true;
let paused = false;
let sessions: SessionRow[] = [];
let watched: string | null = null;
let socket: WebSocket | null = null;
let liveMap: MapFeature[] | null = null;
let lastTick: TickMessage | null = null; // the tick on the screen
let latestTick: TickMessage | null = null; // the last one received (newer while paused)
// How the watched session's stream ended ("session 'ID' closed"); kept so that a redraw after it (the map arriving
// late, a pan) still says so.
let liveEnd = "";
const trails = new Map<number, number[]>();
let leaving: { agent: Agent; until: number }[] = [];
const lastSeen = new Map<number, Agent>();

interface RolloutGroup { id: string; files: string[]; rollouts: ScenarioFile[] }
let groups: RolloutGroup[] = [];
let mode: "none" | "live" | "file" = "none";
let frame = 0;
let playing: number | null = null;

// Test and measurement hooks (tests/viewer/viewer_test.py reads them).
const hooks = {
  renderer: renderer.kind,
  framesDrawn: 0,
  lastDrawn: { tick: -1, agents: -1, ghosts: 0, overlays: 0 },
  ticksReceived: [] as number[],
  ticksDrawn: [] as number[],
  agentsPerTick: {} as Record<number, number>,
  // Per tick drawn: the flags (events and roles) of every agent with any, by id.
  flagsPerTick: {} as Record<number, Record<number, number>>,
  sessions: () => sessions,
  error: () => ($("error").hidden ? "" : $("error").textContent ?? ""),
  mode: () => mode,
  frame: () => frame,
  groups: () => groups.map((g) => ({ id: g.id, rollouts: g.rollouts.length, frames: g.rollouts[0].timestamps.length })),
  setFrame: (f: number) => setFrame(f),
  bench: (ms: number) => bench(ms),
};
(window as unknown as { __viewer: typeof hooks }).__viewer = hooks;

// --- errors and status -----------------------------------------------------------------------------------------
function showError(message: string) {
  const e = $("error");
  e.textContent = message;
  e.hidden = false;
  draw(); // the canvas says it too, so the page is never blank
}
function clearError() {
  $("error").hidden = true;
  $("error").textContent = "";
}
function token(): string {
  return ($<HTMLInputElement>("token").value || "").trim();
}
function authHeaders(): HeadersInit {
  return token() ? { Authorization: `Bearer ${token()}` } : {};
}

async function api<T>(path: string, init: RequestInit = {}): Promise<T> {
  let resp: Response;
  try {
    resp = await fetch(path, { ...init, headers: { ...authHeaders(), ...(init.headers ?? {}) } });
  } catch (e) {
    throw new Error(`cannot reach the viewer's gateway (${path}): ${e}`);
  }
  const text = await resp.text();
  let body: unknown;
  try {
    body = JSON.parse(text);
  } catch {
    throw new Error(`${path}: HTTP ${resp.status}: ${text.slice(0, 200) || "empty answer"}`);
  }
  if (!resp.ok) throw new Error((body as { error?: string }).error ?? `${path}: HTTP ${resp.status}`);
  return body as T;
}

// --- the session list ------------------------------------------------------------------------------------------
async function refreshSessions() {
  try {
    const r = await api<{ server: string; sessions: SessionRow[] }>("/api/sessions");
    sessions = r.sessions;
    $("server").textContent = `server ${r.server}`;
    if ($("error").dataset.source === "sessions") clearError();
    renderSessions();
  } catch (e) {
    sessions = [];
    renderSessions();
    $("error").dataset.source = "sessions";
    showError(String((e as Error).message));
  }
}

function renderSessions() {
  const body = $("sessions").querySelector("tbody")!;
  body.replaceChildren();
  for (const s of sessions) {
    const tr = document.createElement("tr");
    tr.dataset.id = s.id;
    if (s.id === watched) tr.className = "watched";
    const cells = [s.id, s.scenario || "(client-sent)", s.mode, String(s.tick), String(s.agents),
                   s.controllers.length ? s.controllers.join(" ") : "none"];
    cells.forEach((c, i) => {
      const td = document.createElement("td");
      td.textContent = c;
      if (i === 0) { td.className = "id"; td.title = c; }
      tr.appendChild(td);
    });
    tr.onclick = () => { location.hash = `watch=${encodeURIComponent(s.id)}`; };
    body.appendChild(tr);
  }
  $("sessions-note").textContent = sessions.length ? "" : "no live sessions for this token";
}

// --- watching a session ------------------------------------------------------------------------------------------
function stopWatching() {
  if (socket) { socket.onclose = null; socket.close(); }
  socket = null;
  watched = null;
}

function watch(id: string) {
  stopFile();
  stopWatching();
  mode = "live";
  watched = id;
  liveMap = null;
  lastTick = null;
  latestTick = null;
  liveEnd = "";
  trails.clear();
  leaving = [];
  lastSeen.clear();
  hooks.ticksReceived = [];
  hooks.ticksDrawn = [];
  hooks.agentsPerTick = {};
  hooks.flagsPerTick = {};
  follow = true;
  $<HTMLInputElement>("follow").checked = true;
  $("scrub-box").hidden = true;
  renderSessions();
  $("status").textContent = `connecting to session ${id} ...`;
  const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws/watch`);
  socket = ws;
  ws.onopen = () => ws.send(JSON.stringify({ session: id, token: token() }));
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data as string);
    if (msg.type === "error") { $("error").dataset.source = "watch"; showError(msg.message); return; }
    if (msg.type === "end") { liveEnd = msg.message; draw(); return; }
    if (msg.type === "session") {
      if ($("error").dataset.source === "watch") clearError();
      if (msg.map) {
        api<{ features: MapFeature[] }>(`/api/map?session=${encodeURIComponent(id)}`)
          .then((m) => { if (watched === id) { liveMap = m.features; draw(); } })
          .catch((e) => showError(String((e as Error).message)));
      } else {
        $("status").textContent = `session ${id}: the viewer has no map for its scenario`;
      }
      return;
    }
    if (msg.type === "tick") onTick(msg as TickMessage);
  };
  ws.onclose = (ev) => {
    if (socket === ws && watched === id)
      showError(`the connection to the viewer's gateway closed (code ${ev.code}) while watching session ${id}`);
  };
}

function onTick(t: TickMessage) {
  hooks.ticksReceived.push(t.tick);
  for (const a of t.agents) {
    let tr = trails.get(a[0]);
    if (!tr) { tr = []; trails.set(a[0], tr); }
    tr.push(a[2], a[3]);
    if (tr.length > 2 * TRAIL_TICKS) tr.splice(0, tr.length - 2 * TRAIL_TICKS);
  }
  leaving = leaving.filter((l) => l.until > t.tick);
  for (const id of t.left) {
    const last = lastSeen.get(id);
    if (last) leaving.push({ agent: last, until: t.tick + LEAVING_TICKS });
    trails.delete(id);
    lastSeen.delete(id);
  }
  for (const a of t.agents) lastSeen.set(a[0], a);
  latestTick = t;
  if (paused) return;
  lastTick = t;
  draw();
}

// --- rollout files -----------------------------------------------------------------------------------------------
function stopFile() {
  if (playing !== null) clearInterval(playing);
  playing = null;
  $("play").textContent = "Play";
}

async function openFiles(files: FileList) {
  stopWatching();
  renderSessions();
  for (const f of Array.from(files)) {
    try {
      const r = await api<RolloutResponse>("/api/rollout", {
        method: "POST", body: await f.arrayBuffer(), headers: { "X-File-Name": f.name, "Content-Type": "application/octet-stream" },
      });
      if (!r.scenarios.length) throw new Error(`file '${f.name}' holds no scenario`);
      for (const s of r.scenarios) {
        let g = groups.find((x) => x.id === s.id);
        if (!g) { g = { id: s.id, files: [], rollouts: [] }; groups.push(g); }
        g.rollouts.push(s);
        g.files.push(r.file);
      }
      clearError();
    } catch (e) {
      showError(String((e as Error).message));
      return;
    }
  }
  if (!groups.length) return;
  mode = "file";
  const sel = $<HTMLSelectElement>("scenario");
  sel.replaceChildren(...groups.map((g, i) => new Option(`${g.id} (${g.rollouts.length})`, String(i))));
  sel.value = String(groups.length - 1);
  selectGroup();
}

function group(): RolloutGroup { return groups[Number($<HTMLSelectElement>("scenario").value) || 0]; }

function selectGroup() {
  const g = group();
  const sel = $<HTMLSelectElement>("rollout");
  const opts = g.rollouts.map((_, i) => new Option(`${i + 1} of ${g.rollouts.length} (${g.files[i]})`, String(i)));
  if (g.rollouts.length > 1) opts.push(new Option("all, overlaid", "all"));
  sel.replaceChildren(...opts);
  $("rollout-controls").hidden = false;
  $("scrub-box").hidden = false;
  const scrub = $<HTMLInputElement>("scrub");
  scrub.max = String(g.rollouts[0].timestamps.length - 1);
  follow = true;
  $<HTMLInputElement>("follow").checked = true;
  setFrame(g.rollouts[0].current);
  fit();
}

function setFrame(f: number) {
  const g = group();
  if (!g) return;
  frame = Math.max(0, Math.min(f, g.rollouts[0].timestamps.length - 1));
  $<HTMLInputElement>("scrub").value = String(frame);
  draw();
}

function trackAgent(t: Track, f: number): Agent | null {
  const s = t.states[f];
  return s ? [t.id, t.type, s[0], s[1], s[2], s[3], s[4], s[5], s[6]] : null;
}

function fileScene(): { scene: Scene; label: string; ego: Agent | null } {
  const g = group();
  const which = $<HTMLSelectElement>("rollout").value;
  const primary = g.rollouts[which === "all" ? 0 : Number(which) || 0];
  const agents: Agent[] = [];
  const trailMap = new Map<number, number[]>();
  let ego: Agent | null = null;
  const leavingAgents: Agent[] = [];
  for (const t of primary.tracks) {
    const a = trackAgent(t, frame);
    if (!a) {
      // Left within the last LEAVING_TICKS frames: drawn at its last pose.
      for (let k = frame - 1; k >= Math.max(0, frame - LEAVING_TICKS); --k) {
        const last = trackAgent(t, k);
        if (last) { leavingAgents.push(last); break; }
      }
      continue;
    }
    if (t.id === primary.sdc) { a[8] |= Flag.controlled; ego = a; }
    agents.push(a);
    const pts: number[] = [];
    for (let k = Math.max(0, frame - 2 * TRAIL_TICKS); k <= frame; k += 2) {
      const s = t.states[k];
      if (s) pts.push(s[0], s[1]);
    }
    trailMap.set(t.id, pts);
  }
  const overlays: Agent[][] = [];
  if (which === "all")
    for (const r of g.rollouts.slice(1))
      overlays.push(r.tracks.map((t) => trackAgent(t, frame)).filter((a): a is Agent => a !== null));
  const ghosts: Agent[] = [];
  if ($<HTMLInputElement>("ghost").checked && primary.log && frame > primary.current)
    for (const t of primary.log.tracks) {
      const a = t.states[frame] ? trackAgent(t, frame) : null;
      if (a) ghosts.push(a);
    }
  const time = primary.timestamps[frame] - primary.timestamps[0];
  const label = `${g.id}  frame ${frame}/${primary.timestamps.length - 1} (t ${time.toFixed(1)} s${frame <= primary.current ? ", logged" : ", simulated"})  agents ${agents.length}`;
  return { scene: { map: primary.map, agents, lights: primary.lights[frame] ?? [], trails: trailMap, leaving: leavingAgents, ghosts, overlays }, label, ego };
}

// --- drawing -----------------------------------------------------------------------------------------------------
function emptyScene(): Scene {
  return { map: null, agents: [], lights: [], trails: new Map(), leaving: [], ghosts: [], overlays: [] };
}

function draw() {
  let scene = emptyScene();
  let label = "pick a live session or open a rollout file";
  let ego: Agent | null = null;
  let tick = -1;
  if (mode === "live" && lastTick) {
    scene = { map: liveMap, agents: lastTick.agents, lights: lastTick.lights, trails, leaving: leaving.map((l) => l.agent), ghosts: [], overlays: [] };
    ego = lastTick.agents.find((a) => a[8] & Flag.controlled) ?? null;
    const events = lastTick.agents.filter((a) => a[8] & (Flag.overlap | Flag.offRoad | Flag.redLight)).length;
    label = `session ${watched}  tick ${lastTick.tick}  step ${lastTick.step}  t ${lastTick.time.toFixed(1)} s  agents ${lastTick.agents.length}  flagged ${events}${paused ? "  (paused)" : ""}`;
    tick = lastTick.tick;
  } else if (mode === "file" && groups.length) {
    const f = fileScene();
    scene = f.scene; label = f.label; ego = f.ego; tick = frame;
    $("frame").textContent = `${frame}`;
  } else if (mode === "live") {
    label = `session ${watched}: waiting for its first tick`;
  }
  if (mode === "live" && liveEnd) label = `${liveEnd}; ${label}`;
  if (follow && ego) { view.cx = ego[2]; view.cy = ego[3]; }
  else if (follow && !ego && scene.agents.length && view.cx === 0 && view.cy === 0) fitTo(scene);
  const drawn = renderer.draw(scene, view);
  hooks.framesDrawn++;
  hooks.lastDrawn = { tick, agents: drawn, ghosts: scene.ghosts.length, overlays: scene.overlays.length };
  if (mode === "live" && lastTick && hooks.ticksDrawn[hooks.ticksDrawn.length - 1] !== tick) {
    hooks.ticksDrawn.push(tick);
    hooks.agentsPerTick[tick] = drawn;
    const flags: Record<number, number> = {};
    for (const a of lastTick.agents) if (a[8]) flags[a[0]] = a[8];
    hooks.flagsPerTick[tick] = flags;
  }
  $("status").textContent = label;
}

function fitTo(scene: Scene) {
  const b = scene.map ? renderer.mapBounds(scene.map) : null;
  let [x0, y0, x1, y1] = b ?? [Infinity, Infinity, -Infinity, -Infinity];
  if (!b) for (const a of scene.agents) { x0 = Math.min(x0, a[2]); y0 = Math.min(y0, a[3]); x1 = Math.max(x1, a[2]); y1 = Math.max(y1, a[3]); }
  if (!Number.isFinite(x0)) return;
  view.cx = (x0 + x1) / 2; view.cy = (y0 + y1) / 2;
  view.scale = Math.max(0.05, Math.min(40, 0.9 * Math.min(canvas.clientWidth / Math.max(x1 - x0, 10), canvas.clientHeight / Math.max(y1 - y0, 10))));
}

function fit() {
  follow = false;
  $<HTMLInputElement>("follow").checked = false;
  if (mode === "file" && groups.length) fitTo(fileScene().scene);
  else if (lastTick) fitTo({ ...emptyScene(), map: liveMap, agents: lastTick.agents });
  draw();
}

// Redraws for `ms` milliseconds at the display's rate, moving the view and (for a file) the frame every time: the
// frame rate docs/viewer.md reports. Returns frames per second and the mean time a draw took, its rasterisation
// included (Renderer.flush).
function bench(ms: number): Promise<{ fps: number; frames: number; drawMs: number; renderer: string }> {
  return new Promise((resolve) => {
    const start = performance.now();
    let frames = 0, drawTime = 0;
    follow = false;
    const step = () => {
      const now = performance.now();
      if (now - start >= ms) {
        resolve({ fps: (frames * 1000) / (now - start), frames, drawMs: drawTime / Math.max(frames, 1), renderer: renderer.kind });
        return;
      }
      if (mode === "file" && groups.length) frame = (frame + 1) % group().rollouts[0].timestamps.length;
      view.cx += 0.2;
      const t0 = performance.now();
      draw();
      renderer.flush();
      drawTime += performance.now() - t0;
      frames++;
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  });
}

// --- controls ----------------------------------------------------------------------------------------------------
function setPaused(p: boolean) {
  paused = p;
  $("pause").textContent = p ? "Resume" : "Pause";
  if (!p && mode === "live") lastTick = latestTick; // resume at the latest tick received
  if (mode === "file") {
    if (p) stopFile();
  }
  draw();
}

function zoom(factor: number, sx?: number, sy?: number) {
  const rect = canvas.getBoundingClientRect();
  const px = sx ?? rect.width / 2, py = sy ?? rect.height / 2;
  // Keep the world point under the cursor in place.
  const wx = view.cx + (px - rect.width / 2) / view.scale, wy = view.cy - (py - rect.height / 2) / view.scale;
  view.scale = Math.max(0.05, Math.min(200, view.scale * factor));
  if (!follow) {
    view.cx = wx - (px - rect.width / 2) / view.scale;
    view.cy = wy + (py - rect.height / 2) / view.scale;
  }
  draw();
}

let drag: { x: number; y: number } | null = null;
canvas.addEventListener("mousedown", (e) => { drag = { x: e.clientX, y: e.clientY }; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", (e) => {
  if (!drag) return;
  if (follow) { follow = false; $<HTMLInputElement>("follow").checked = false; }
  view.cx -= (e.clientX - drag.x) / view.scale;
  view.cy += (e.clientY - drag.y) / view.scale;
  drag = { x: e.clientX, y: e.clientY };
  draw();
});
canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  const rect = canvas.getBoundingClientRect();
  zoom(Math.exp(-e.deltaY * 0.0015), e.clientX - rect.left, e.clientY - rect.top);
}, { passive: false });
$("zoom-in").onclick = () => zoom(1.5);
$("zoom-out").onclick = () => zoom(1 / 1.5);
$("fit").onclick = () => fit();
$<HTMLInputElement>("follow").onchange = (e) => { follow = (e.target as HTMLInputElement).checked; draw(); };
$("pause").onclick = () => setPaused(!paused);
window.addEventListener("keydown", (e) => {
  if ((e.target as HTMLElement).tagName === "INPUT") return;
  if (e.key === " ") { e.preventDefault(); setPaused(!paused); }
  if (e.key === "f") { follow = !follow; $<HTMLInputElement>("follow").checked = follow; draw(); }
  if (mode === "file" && e.key === "ArrowRight") setFrame(frame + 1);
  if (mode === "file" && e.key === "ArrowLeft") setFrame(frame - 1);
});
$<HTMLInputElement>("scrub").oninput = (e) => setFrame(Number((e.target as HTMLInputElement).value));
$("play").onclick = () => {
  if (playing !== null) { stopFile(); return; }
  $("play").textContent = "Stop";
  playing = window.setInterval(() => {
    const g = group();
    if (!g || frame >= g.rollouts[0].timestamps.length - 1) { stopFile(); return; }
    setFrame(frame + 1);
  }, 100);
};
$<HTMLSelectElement>("scenario").onchange = () => selectGroup();
$<HTMLSelectElement>("rollout").onchange = () => draw();
$<HTMLInputElement>("ghost").onchange = () => draw();
$<HTMLInputElement>("file").onchange = (e) => {
  const files = (e.target as HTMLInputElement).files;
  if (files && files.length) void openFiles(files);
};
$("connect").onclick = () => {
  sessionStorage.setItem("ss-viewer-token", token());
  clearError();
  void refreshSessions();
  if (watched) watch(watched);
};
window.addEventListener("resize", () => draw());
window.addEventListener("hashchange", route);

function route() {
  const m = /^#watch=(.+)$/.exec(location.hash);
  if (m) watch(decodeURIComponent(m[1]));
}

// The legend: what each colour and mark means.
function legend() {
  const items: [string, string][] = [
    [TYPE_COLOURS[0], "vehicle"], [TYPE_COLOURS[1], "pedestrian"], [TYPE_COLOURS[2], "cyclist"],
    [EGO_COLOUR, "controlled ego"], ["#00b8e6", "entered (outline)"], ["#ffffff", "leaving (dashed)"],
    ["#e53935", "overlap (ring)"], ["#8d4e00", "off road (dashed)"], ["#e53935", "ran a red (triangle)"],
    [LIGHT_COLOURS[1], "light green"], [LIGHT_COLOURS[2], "light yellow"], [LIGHT_COLOURS[3], "light red"],
    ["#555555", "logged future (ghost)"], ["#2e2e2e", "road edge"], ["#b9c0cc", "lane centre"],
    ["rgba(70,90,200,0.4)", "crosswalk"],
  ];
  $("legend").replaceChildren(...items.map(([c, t]) => {
    const li = document.createElement("li");
    const i = document.createElement("i");
    i.style.background = c;
    li.append(i, t);
    return li;
  }));
}

legend();
$<HTMLInputElement>("token").value = sessionStorage.getItem("ss-viewer-token") ?? "";
draw();
void refreshSessions();
setInterval(() => { if (!document.hidden) void refreshSessions(); }, 2000);
route();
