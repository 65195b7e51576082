// The server's state as the gateway forwards it: each topic's JSON view, from its field list in
// protocol/include/ignav/protocol/types.hpp; protocol/idl/ignav.idl the meaning of every field.
// Lengths in mm, angles in rad, matrices row-major 4x4.

export type Vec3 = [number, number, number];

export interface WorkflowState {
  session_id: string;
  phase: string;
  allowed_commands: string[];
  revision: number;
  last_event: string;
  safety_notice?: string; // "" unless a safeguard is weakened (docs/OPENIGTLINK.md)
  target_ids?: number[]; // every target there is, in planned order
}

export interface RobotState {
  name: string;
  config_path: string;
  r_min_mm: number;
  r_max_mm: number;
  feasible_volume_cm3: number;
  tissue: string;
  feature_points_robot: Vec3[];
}

export interface VolumeState {
  status: string; // none | loading | loaded | failed
  source: string;
  message: string;
  dims: Vec3;
  spacing_mm: Vec3;
  ijk_to_lps: number[];
  hu_min: number;
  hu_max: number;
  progress: [number, number]; // files done, of total
}

export interface RegistrationState {
  status: string; // none | registered | rejected
  message: string;
  kind: string;
  image_points: Vec3[];
  robot_points: Vec3[];
  image_to_robot: number[];
  scale: number;
  fre_mm: number;
  residuals_mm: number[];
  auto_detected: boolean;
}

export interface TargetState {
  id: number;
  lps: Vec3;
  robot: Vec3;
  registered: boolean;
  reachable: boolean;
  reach: string;
  message: string;
  joints: [number, number, number]; // theta_c_rad, z_c_mm, z_s_mm
  steps: [number, number, number];
  tre_mm: number;
  tre_warning: boolean;
  order: number;
  predicted_deviation_mm: number | null;
  status: string; // planned | reached | unreachable | unregistered | outside_volume
  path_lps?: Vec3[]; // absent from servers that predate docs/WEB.md
  // A CT is loaded and the target lies outside it (never imaged): lock_plan refuses it.
  outside_volume?: boolean; // absent from servers that predate issue 26, as are:
  path_warning?: string; // "" or: the planned path leaves the loaded CT (where, for how long)
  // Aimed with a tissue profile (use_tissue, issue 23): `joints` are then the compensated joints,
  // whose tip that tissue's model deflects onto the target; the nominal ones (exact IK), where
  // they would land and where the compensated ones land. Absent from servers before issue 23.
  compensated?: boolean;
  aim_tissue?: string;
  nominal_joints?: [number, number, number];
  nominal_landing_robot?: Vec3;
  predicted_landing_robot?: Vec3;
  // The whole needle against every avoided structure (issue 41; absent before it): one row per
  // structure, the refusal lock_plan would give ("" none) and the operator's reason to plan it
  // all the same ("" none).
  clearances?: ClearanceState[];
  clearance_refusal?: string;
  clearance_override?: string;
}

// One avoided structure against one target's needle (cannula and stylet with their radii).
export interface ClearanceState {
  structure: string;
  distance_mm: number; // the needle's surface to the structure's at the closest; < 0: into it
  margin_mm: number; // the structure's, by the site or structure_role
  uncertainty_mm: number; // registration error and predicted deflection there
  part: string; // cannula | stylet: where on the needle the closest point is
  needle_lps: Vec3;
  structure_lps: Vec3;
  beyond_reach: boolean; // farther than the search looked: distance_mm is a lower bound
  too_close: boolean; // distance < margin + uncertainty
}

// The patient's structures on the CT (load_structures), the targets proposed to fill one
// (propose_targets) and where to place the robot (place_robot); issue 41, docs/ANATOMY.md.
export interface StructureInfo {
  name: string;
  colour_rgb: Vec3; // 0-1
  role: string; // target | avoid | shown
  margin_mm: number;
  voxels: number;
  volume_cm3: number;
  bounds_lps: number[]; // min x, y, z, max x, y, z
}

export interface ProposedTargetInfo {
  id: number;
  lps: Vec3;
}

export interface PlacementInfo {
  coverage: number; // 0-1 of the structure
  origin_lps: Vec3; // the robot's origin (the cannula's proximal end)
  axis_lps: Vec3; // unit, the direction of insertion
  entry_lps: Vec3; // where the axis enters the skin
  tilt_deg: number; // from the approach
  shift_mm: number; // of the axis from the structure's centroid
  skin_distance_mm: number; // origin to entry
  skin_seen: boolean; // false: no skin along the axis within the CT
}

export interface StructuresState {
  status: string; // none | loading | loaded | failed
  source: string;
  message: string;
  site: string;
  structures: StructureInfo[];
  proposal_status: string; // none | proposing | proposed | failed
  proposal_message: string;
  proposed: ProposedTargetInfo[];
  proposal_progress_done: number; // proposing: units done (a seed plan: thousandths), of total
  proposal_progress_total: number;
  placement_status: string; // none | placing | placed | failed
  placement_message: string;
  placement_structure: string;
  placement_progress_done: number;
  placement_progress_total: number;
  placements: PlacementInfo[]; // the best first
  mounted_status: string; // none | measuring | measured | failed
  mounted_message: string;
  mounted_coverage: number | null; // null before it is measured (NaN on the wire)
  mounted_entry_mm: number | null;
  mounted_axis_deg: number | null;
  dose_status: string; // none | computing | computed | failed
  dose_message: string;
  dose: DoseMetricsInfo[];
}

// One structure's dose metrics (compute_dose); null: not judged for its role (NaN on the wire).
export interface DoseMetricsInfo {
  structure: string;
  which: string; // planned | delivered
  d90_percent: number | null;
  v100: number | null;
  v150: number | null;
  d10_percent: number | null;
  dmax_percent: number | null;
  d2cc_gy: number | null;
}

export interface PlannedMove {
  kind: string;
  steps: [number, number, number];
  duration_s: number;
}

export interface ApprovalState {
  status: string; // none | pending (also once expired: the server then refuses it)
  plan_id: number;
  digest: string;
  target_id: number; // 0: the final retraction of the stylet
  summary: string;
  from_steps: [number, number, number];
  moves: PlannedMove[];
  duration_s: number;
  tre_mm: number;
  expires_in_s: number; // at publication: a late page must not count from it
  expires_at_unix_s: number; // the server's clock (Unix s)
  approvers: string[];
}

export interface MotionState {
  controller: string;
  state: string; // disconnected | idle | moving | fault
  lifecycle: string; // unconfigured | connecting | active | lost | shut_down
  fault: string;
  plan_id: number;
  target_id: number;
  move_index: number;
  move_count: number;
  move_kind: string;
  steps: [number, number, number];
  goal_steps: [number, number, number];
  verified_steps: [number, number, number];
  joints: [number, number, number];
  tip_robot: Vec3;
  tip_lps: Vec3 | null;
  uptime_s: number;
  needle_lps?: Vec3[]; // cannula base, cannula tip, the stylet's arc (absent before issue 43)
}

export interface HealthState {
  version: string;
  session_id: string;
  session_dir: string;
  uptime_s: number;
  commands_accepted: number;
  commands_rejected: number;
  journal: string;
  igtl_clients?: number; // OpenIGTLink clients connected now
  // The server's wall clock (Unix s) when it wrote this sample, once a second: what an approval's
  // expires_at_unix_s is counted down against (clock.ts). Absent from servers before issue 26.
  server_time_unix_s?: number;
  robot_id?: string; // which robot this server drives (docs/DEPLOYMENT.md); absent before issue 24
  host?: string;
  started_unix_s?: number;
}

// ---- the closed loop (issue 23): the confirmation CT, its seeds and the targeting error -------

export interface ErrorStats {
  count: number;
  mean_mm: number;
  sd_mm: number; // sample SD (n - 1)
  min_mm: number;
  max_mm: number;
  rms_mm: number;
}

export interface SeedState {
  id: number;
  lps: Vec3; // on the confirmation CT
  robot: Vec3; // through the confirmation CT's registration
  length_mm: number; // 0 for a placed one
  width_mm: number;
  placed: boolean; // by place_seed
  rejected: boolean; // by reject_seed
  target_id: number; // matched to (0: none)
  kind?: string; // "seed" | "tip" (the needle still in the scan: where its stylet ended)
  path_lps?: Vec3[]; // a tip's needle centreline on the confirmation CT, ending at it
}

export interface MeasuredTargetState {
  target_id: number;
  seed_id: number;
  matched: string; // detected | accepted | placed
  planned_robot: Vec3;
  actual_robot: Vec3;
  planned_lps: Vec3;
  actual_lps: Vec3; // on the confirmation CT
  error_robot: Vec3; // actual - planned
  error_lps: Vec3;
  error_mm: number;
  lateral_mm: number; // across the insertion axis
  radial_mm: number;
  tangential_mm: number;
  depth_mm: number; // + deeper than planned
  predicted_robot: Vec3 | null; // the model's landing, when it predicted one
  predicted_error_mm: number; // its distance from the plan (when predicted)
}

export interface FittedTissueState {
  name: string;
  lambda1: number;
  lambda2: number;
  lambda1_se: number; // standard errors
  lambda2_se: number;
  rms_mm: number; // measured - predicted landing
  rms_bicycle_mm: number; // the plain bicycle model on the same data
  rms_no_deflection_mm: number; // the errors as measured
  targets: number;
  limit: string; // "" or the admissibility limit a parameter ended on
  yaml: string; // the configs/tissues.yaml entry
}

export interface VerificationState {
  status: string; // none | measuring | measured | unmatched (message says why)
  source: string; // the confirmation CT measured
  measuring_source: string; // the one being measured ("" none)
  message: string;
  registration_reused: boolean; // the session's registration (the markers where they were)
  marker_shift_mm: number | null; // null: the scan came with its registration (no markers compared)
  fre_mm: number;
  image_to_robot: number[]; // the confirmation CT's
  detection_summary: string;
  seeds: SeedState[];
  targets: MeasuredTargetState[]; // per measured target
  missing_targets: number[]; // reached, without a seed
  extra_seeds: number[]; // seed ids matched to no target
  error: ErrorStats; // |error|
  lateral: ErrorStats; // |lateral|
  depth: ErrorStats; // signed
  summary: string; // mean ± SD, max, min, RMS, missing, extra
  fitted_tissues: FittedTissueState[];
  aim_tissue: string; // the profile the plan aims with ("" none)
}

// Every topic is absent until the server first publishes it.
export interface ServerState {
  workflow?: WorkflowState;
  robot?: RobotState;
  volume?: VolumeState;
  registration?: RegistrationState;
  targets?: Record<string, TargetState>;
  approval?: ApprovalState;
  motion?: MotionState;
  health?: HealthState;
  verification?: VerificationState; // absent from servers before issue 23
  structures?: StructuresState; // absent from servers before issue 41
}

// ---- gateway messages (docs/WEB.md) ------------------------------------------------------

export interface HelloMessage {
  type: "hello";
  client_id: string;
  robot_id: string; // the one robot this gateway serves
  subject: string;
  security: boolean;
  version: string;
  permitted: string[]; // the commands (and "approve") this gateway's DDS identity may publish
}

export interface ConnectionMessage {
  type: "connection";
  server: boolean;
}

export interface StateMessage {
  type: "state";
  state: ServerState;
}

export interface ReplyMessage {
  type: "reply";
  seq: number;
  accepted: boolean;
  error_code: string;
  message: string;
  target_id: number;
  revision: number;
  job: number; // the background job the command started (its JobOutcomeMessage), 0: none
}

// What became of a background job (a CT load, a marker detection, a confirmation measurement):
// every page hears it; the page whose reply named the job shows it.
export interface JobOutcomeMessage {
  type: "job_outcome";
  job: number;
  kind: string; // "CT load", "marker detection", ...
  input: string; // the outcome input: "volume_loaded", ...
  status: "done" | "failed" | "stale";
  message: string;
  revision: number;
}

export interface SliceMessage {
  type: "slice";
  seq: number;
  ok: boolean;
  message: string;
  width: number;
  height: number;
  pixel_to_lps: number[];
  png_base64: string;
}

export interface ErrorMessage {
  type: "error";
  seq: number;
  code: string;
  message: string;
}

export type GatewayMessage =
  | HelloMessage
  | ConnectionMessage
  | StateMessage
  | ReplyMessage
  | JobOutcomeMessage
  | SliceMessage
  | SceneMessage
  | ErrorMessage;

// What a request is answered with.
export type Answer = ReplyMessage | SliceMessage | SceneMessage | ErrorMessage;

export type ViewName = "axial" | "sagittal" | "coronal";

export interface SliceRequest {
  op: "slice";
  view: ViewName;
  centre_lps: Vec3;
  size_px: number;
  pixel_mm: number;
  window: number;
  level: number;
  overlays: "none" | "region" | "all";
}

export interface CommandRequest {
  op: "command";
  kind: string;
  points: Vec3[];
  ids: number[];
  path: string;
}

export interface ApproveRequest {
  op: "approve";
  plan_id: number;
  digest: string;
}

export interface EmergencyStopRequest {
  op: "emergency_stop";
}

// A part of the 3D view's scene (issue 43): the CT by slabs, or the surfaces.
export interface SceneRequest {
  op: "scene";
  part: "volume" | "surfaces";
  first_slice?: number;
  max_voxels_per_axis?: number;
}

export interface SceneSurfaceMessage {
  name: string;
  kind: string; // structure | feasible | isodose
  colour_rgb: Vec3; // 0-1
  points_base64: string; // float32 x, y, z per vertex, little-endian
  triangles_base64: string; // uint32, three per triangle
}

export interface SceneMessage {
  type: "scene";
  seq: number;
  ok: boolean;
  message: string;
  part: string;
  volume_id: string;
  dims: Vec3;
  ijk_to_lps: number[];
  value_scale: number;
  value_offset: number;
  first_slice: number;
  slice_count: number;
  voxels_base64: string; // int16, little-endian, i fastest
  surfaces: SceneSurfaceMessage[];
}

export type Request = SliceRequest | SceneRequest | CommandRequest | ApproveRequest | EmergencyStopRequest;
