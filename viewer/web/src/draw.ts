// Canvas 2D drawing of a scene: the map by feature type, agents as oriented boxes by type and role, heading, trails,
// lights at their stop lines, the engine's events. Canvas 2D was chosen over WebGL by its measured frame rate
// (docs/viewer.md): 300 agents on a 2,000-feature map draw well within a 60 Hz frame in headless Chromium without a
// GPU, so the simpler API stays.
import { Agent, FeatureType, Flag, Light, MapFeature } from "./types";

export const TYPE_COLOURS = ["#3a6fd8", "#e08a1e", "#2aa84a", "#8a8a8a"]; // vehicle, pedestrian, cyclist, other
export const EGO_COLOUR = "#d81b60";
export const LIGHT_COLOURS = ["#9e9e9e", "#1db954", "#f5b400", "#e53935"]; // unknown, green, yellow, red

export interface View {
  cx: number; // world point at the canvas centre
  cy: number;
  scale: number; // pixels per metre
}

export interface Scene {
  map: MapFeature[] | null;
  agents: Agent[];
  lights: Light[];
  trails: Map<number, number[]>; // agent id -> x0, y0, x1, y1, ... oldest first
  leaving: Agent[]; // agents that left lately, at their last pose
  ghosts: Agent[]; // the logged future (rollout files)
  overlays: Agent[][]; // other rollouts, drawn faded
}

interface MapPaths {
  source: MapFeature[];
  lanes: Path2D;
  whiteLines: Path2D;
  yellowLines: Path2D;
  edges: Path2D;
  crosswalks: Path2D;
  bumps: Path2D;
  driveways: Path2D;
  stopSigns: Path2D;
  bounds: [number, number, number, number];
}

function polyline(p: Path2D, pts: number[], close: boolean) {
  if (pts.length < 2) return;
  p.moveTo(pts[0], pts[1]);
  for (let i = 2; i + 1 < pts.length; i += 2) p.lineTo(pts[i], pts[i + 1]);
  if (close) p.closePath();
}

function buildMap(features: MapFeature[]): MapPaths {
  const m: MapPaths = {
    source: features, lanes: new Path2D(), whiteLines: new Path2D(), yellowLines: new Path2D(), edges: new Path2D(),
    crosswalks: new Path2D(), bumps: new Path2D(), driveways: new Path2D(), stopSigns: new Path2D(),
    bounds: [Infinity, Infinity, -Infinity, -Infinity],
  };
  for (const f of features) {
    for (let i = 0; i + 1 < f.pts.length; i += 2) {
      m.bounds[0] = Math.min(m.bounds[0], f.pts[i]);
      m.bounds[1] = Math.min(m.bounds[1], f.pts[i + 1]);
      m.bounds[2] = Math.max(m.bounds[2], f.pts[i]);
      m.bounds[3] = Math.max(m.bounds[3], f.pts[i + 1]);
    }
    switch (f.type) {
      case FeatureType.lane: polyline(m.lanes, f.pts, false); break;
      // RoadLineType 4..8 are yellow lines.
      case FeatureType.roadLine: polyline(f.subtype >= 4 && f.subtype <= 8 ? m.yellowLines : m.whiteLines, f.pts, false); break;
      case FeatureType.roadEdge: polyline(m.edges, f.pts, false); break;
      case FeatureType.crosswalk: polyline(m.crosswalks, f.pts, true); break;
      case FeatureType.speedBump: polyline(m.bumps, f.pts, true); break;
      case FeatureType.driveway: polyline(m.driveways, f.pts, true); break;
      case FeatureType.stopSign:
        if (f.pts.length >= 2) {
          m.stopSigns.moveTo(f.pts[0] + 1.2, f.pts[1]);
          m.stopSigns.arc(f.pts[0], f.pts[1], 1.2, 0, 2 * Math.PI);
        }
        break;
    }
  }
  return m;
}

// Adds an oriented box (centre, heading, length, width, grown by `grow` metres, each half at least `min`) to `p`.
function box(p: Path2D, x: number, y: number, h: number, l: number, w: number, grow = 0, min = 0.25) {
  const c = Math.cos(h), s = Math.sin(h);
  const hl = Math.max(l / 2, min) + grow, hw = Math.max(w / 2, min) + grow;
  p.moveTo(x + c * hl - s * hw, y + s * hl + c * hw);
  p.lineTo(x - c * hl - s * hw, y - s * hl + c * hw);
  p.lineTo(x - c * hl + s * hw, y - s * hl - c * hw);
  p.lineTo(x + c * hl + s * hw, y + s * hl - c * hw);
  p.closePath();
}

export class Renderer {
  readonly kind = "canvas2d";
  private ctx: CanvasRenderingContext2D;
  private map: MapPaths | null = null;

  constructor(private canvas: HTMLCanvasElement) {
    const ctx = canvas.getContext("2d", { alpha: false });
    if (!ctx) throw new Error("this browser gives no 2D canvas");
    this.ctx = ctx;
  }

  // Waits for the canvas to be rasterised (Chromium records 2D calls and rasterises later): reading a pixel back
  // makes a frame's measured time include its pixels.
  flush() {
    this.ctx.getImageData(0, 0, 1, 1);
  }

  // The map's extent, for the first view of a session.
  mapBounds(features: MapFeature[]): [number, number, number, number] | null {
    if (!this.map || this.map.source !== features) this.map = buildMap(features);
    const b = this.map.bounds;
    return Number.isFinite(b[0]) ? b : null;
  }

  // Draws the scene; returns the number of agents drawn (the scene's current agents).
  draw(scene: Scene, view: View): number {
    const { canvas, ctx } = this;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(canvas.clientWidth * dpr), h = Math.round(canvas.clientHeight * dpr);
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w;
      canvas.height = h;
    }
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#eeefe9";
    ctx.fillRect(0, 0, w, h);
    const k = view.scale * dpr;
    // World to screen: y up in the world, down on the screen.
    ctx.setTransform(k, 0, 0, -k, w / 2 - view.cx * k, h / 2 + view.cy * k);
    const px = 1 / k; // one screen pixel in metres
    ctx.lineJoin = "round";
    ctx.lineCap = "round";

    if (scene.map) {
      if (!this.map || this.map.source !== scene.map) this.map = buildMap(scene.map);
      const m = this.map;
      ctx.fillStyle = "rgba(0,0,0,0.06)";
      ctx.fill(m.driveways);
      ctx.fillStyle = "rgba(70,90,200,0.22)";
      ctx.fill(m.crosswalks);
      ctx.fillStyle = "rgba(150,60,170,0.35)";
      ctx.fill(m.bumps);
      ctx.setLineDash([]);
      ctx.lineWidth = 1 * px;
      ctx.strokeStyle = "#b9c0cc";
      ctx.stroke(m.lanes);
      ctx.lineWidth = 1.4 * px;
      ctx.strokeStyle = "#8f8f8f";
      ctx.stroke(m.whiteLines);
      ctx.strokeStyle = "#d9a400";
      ctx.stroke(m.yellowLines);
      ctx.lineWidth = 2.2 * px;
      ctx.strokeStyle = "#2e2e2e";
      ctx.stroke(m.edges);
      ctx.fillStyle = "#c62828";
      ctx.fill(m.stopSigns);
    }

    // Lights: the stop line across the lane and a disc in the state's colour.
    for (let s = 0; s < 4; ++s) {
      const line = new Path2D(), disc = new Path2D();
      let any = false;
      for (const l of scene.lights) {
        if (l[4] !== s) continue;
        any = true;
        const c = Math.cos(l[3]), sn = Math.sin(l[3]);
        line.moveTo(l[1] + sn * 2, l[2] - c * 2);
        line.lineTo(l[1] - sn * 2, l[2] + c * 2);
        disc.moveTo(l[1] + 0.9, l[2]);
        disc.arc(l[1], l[2], 0.9, 0, 2 * Math.PI);
      }
      if (!any) continue;
      ctx.strokeStyle = LIGHT_COLOURS[s];
      ctx.lineWidth = Math.max(0.5, 3 * px);
      ctx.stroke(line);
      ctx.fillStyle = LIGHT_COLOURS[s];
      ctx.fill(disc);
    }

    // Trails, by type.
    const trails = [new Path2D(), new Path2D(), new Path2D(), new Path2D()];
    const typeOf = new Map<number, number>();
    for (const a of scene.agents) typeOf.set(a[0], a[1]);
    for (const [id, pts] of scene.trails) {
      const t = typeOf.get(id);
      if (t !== undefined) polyline(trails[Math.min(t, 3)], pts, false);
    }
    ctx.globalAlpha = 0.45;
    ctx.lineWidth = 2 * px;
    for (let t = 0; t < 4; ++t) {
      ctx.strokeStyle = TYPE_COLOURS[t];
      ctx.stroke(trails[t]);
    }
    ctx.globalAlpha = 1;

    // The logged future and other rollouts: outlines only.
    if (scene.ghosts.length) {
      const p = new Path2D();
      for (const a of scene.ghosts) box(p, a[2], a[3], a[4], a[5], a[6]);
      ctx.setLineDash([4 * px, 3 * px]);
      ctx.lineWidth = 1.5 * px;
      ctx.strokeStyle = "#555";
      ctx.stroke(p);
      ctx.setLineDash([]);
    }
    if (scene.overlays.length) {
      ctx.globalAlpha = 0.3;
      for (const agents of scene.overlays) {
        const byType = [new Path2D(), new Path2D(), new Path2D(), new Path2D()];
        for (const a of agents) box(byType[Math.min(a[1], 3)], a[2], a[3], a[4], a[5], a[6]);
        for (let t = 0; t < 4; ++t) {
          ctx.fillStyle = TYPE_COLOURS[t];
          ctx.fill(byType[t]);
        }
      }
      ctx.globalAlpha = 1;
    }
    if (scene.leaving.length) {
      const p = new Path2D();
      for (const a of scene.leaving) box(p, a[2], a[3], a[4], a[5], a[6]);
      ctx.globalAlpha = 0.5;
      ctx.setLineDash([2 * px, 2 * px]);
      ctx.lineWidth = 1.5 * px;
      ctx.strokeStyle = "#333";
      ctx.stroke(p);
      ctx.setLineDash([]);
      ctx.globalAlpha = 1;
    }

    // Agents: boxes filled by type (the ego in its own colour), outlined; heading as a line to the front.
    const fills = [new Path2D(), new Path2D(), new Path2D(), new Path2D()];
    const ego = new Path2D(), entered = new Path2D(), heading = new Path2D();
    const overlap = new Path2D(), offRoad = new Path2D(), red = new Path2D();
    let drawn = 0;
    for (const a of scene.agents) {
      const [, type, x, y, h, l, w, , flags] = a;
      // At least 5 pixels across, so a pedestrian stays visible when the whole map is on the screen.
      box(flags & Flag.controlled ? ego : fills[Math.min(type, 3)], x, y, h, l, w, 0, 2.5 * px);
      if (flags & Flag.entered) box(entered, x, y, h, l, w, 0.4, 2.5 * px);
      const r = Math.max(l, 0.5) / 2;
      heading.moveTo(x, y);
      heading.lineTo(x + Math.cos(h) * r, y + Math.sin(h) * r);
      const ring = Math.max(l, w, 1) / 2 + 0.8;
      if (flags & Flag.overlap) {
        overlap.moveTo(x + ring, y);
        overlap.arc(x, y, ring, 0, 2 * Math.PI);
      }
      if (flags & Flag.offRoad) box(offRoad, x, y, h, l, w, 0.9);
      if (flags & Flag.redLight) {
        red.moveTo(x, y + ring + 1.6);
        red.lineTo(x - 1.2, y + ring);
        red.lineTo(x + 1.2, y + ring);
        red.closePath();
      }
      ++drawn;
    }
    ctx.lineWidth = 1 * px;
    ctx.strokeStyle = "#1b1b1b";
    for (let t = 0; t < 4; ++t) {
      ctx.fillStyle = TYPE_COLOURS[t];
      ctx.fill(fills[t]);
      ctx.stroke(fills[t]);
    }
    ctx.fillStyle = EGO_COLOUR;
    ctx.fill(ego);
    ctx.lineWidth = 2 * px;
    ctx.stroke(ego);
    ctx.strokeStyle = "#00b8e6";
    ctx.stroke(entered);
    ctx.lineWidth = 1.5 * px;
    ctx.strokeStyle = "#ffffff";
    ctx.stroke(heading);
    ctx.lineWidth = 2.5 * px;
    ctx.strokeStyle = "#e53935";
    ctx.stroke(overlap);
    ctx.setLineDash([3 * px, 2 * px]);
    ctx.strokeStyle = "#8d4e00";
    ctx.stroke(offRoad);
    ctx.setLineDash([]);
    ctx.fillStyle = "#e53935";
    ctx.fill(red);
    return drawn;
  }
}
