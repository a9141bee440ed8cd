// What the gateway sends (viewer/convert.h is the other half of these formats).

// [id, type, x, y, heading, length, width, speed, flags]; type 0 vehicle, 1 pedestrian, 2 cyclist, 3 other.
export type Agent = [number, number, number, number, number, number, number, number, number];
// [lane, x, y, heading, state]; state 0 unknown, 1 green, 2 yellow, 3 red.
export type Light = [number, number, number, number, number];

export const Flag = { controlled: 1, entered: 2, overlap: 4, offRoad: 8, redLight: 16 } as const;

// MapFeatureType of the proto.
export const FeatureType = { lane: 0, roadLine: 1, roadEdge: 2, stopSign: 3, crosswalk: 4, speedBump: 5, driveway: 6 } as const;

export interface MapFeature {
  id: number;
  type: number;
  subtype: number;
  pts: number[]; // x0, y0, x1, y1, ...
}

export interface SessionRow {
  id: string;
  scenario: string;
  mode: string;
  tick: number;
  agents: number;
  controllers: number[];
  tick_hz: number;
}

export interface TickMessage {
  type: "tick";
  tick: number;
  step: number;
  time: number;
  agents: Agent[];
  lights: Light[];
  left: number[];
}

// A track of a scenario file: per frame [x, y, heading, length, width, speed, flags] or null.
export type TrackState = [number, number, number, number, number, number, number];
export interface Track {
  id: number;
  type: number;
  states: (TrackState | null)[];
}

export interface ScenarioFile {
  id: string;
  timestamps: number[];
  current: number;
  sdc: number;
  map: MapFeature[];
  tracks: Track[];
  lights: Light[][];
  log: { timestamps: number[]; tracks: Track[] } | null;
}

export interface RolloutResponse {
  file: string;
  scenarios: ScenarioFile[];
}
