// The web viewer (docs/WEB.md): the server's state as the gateway streams it, three slice views
// sharing one centre point, and the operator's workflow as clicks: fiducials, then targets,
// then lock, approve, watch. Every click is a command; the server decides and the reply shows.
import { connectionView } from "./alerts";
import { ServerClock, approvalPublishedAt_s } from "./clock";
import {
  add,
  clampAlong,
  fittingPixelMm,
  formatLps,
  loadedVolumeKey,
  parseLps,
  scale,
  spacingAlong,
  viewCentre,
  volumeCentre,
} from "./geometry";
import { byId } from "./dom";
import { Panels } from "./panels";
import { GatewaySocket, type SocketStatus } from "./socket";
import type { Answer, HelloMessage, Request, ServerState, Vec3, ViewName } from "./state";
import { targetDisplay } from "./status";
import { placementAxis } from "./structures";
import { StructuresPanel, boundsCentre } from "./structures_panel";
import { seedMarkers } from "./verification";
import { type Selection, View3d } from "./view3d";
import {
  type ClickMode,
  type Overlay,
  SliceView,
  type ViewHost,
  type ViewSettings,
  kSizePx,
  kViewNormal,
} from "./views";

const kZoomStep = 1.25;
const kPlaneToleranceVoxels = 1.5; // a marker this near the plane is drawn on it
const kWindowPresets: Record<string, [number, number]> = { bone: [2000, 300], soft: [400, 40] };

// ---- what the page knows -------------------------------------------------------------------

let state: ServerState = {};
let hello: HelloMessage | null = null;
let socketStatus: SocketStatus = { open: false, retry_in_ms: 0 };
let serverConnected: boolean | null = null;
let settings: ViewSettings | null = null; // null until a volume is loaded; centre_lps is shared
// Where each view was last centred in its own plane (see viewCentre): a scroll moves the shared
// centre along one view's normal and leaves the others' slices where they are.
let pans: Record<ViewName, Vec3> | null = null;
let lastScroll: { view: ViewName; step: number } | null = null; // which way, for fetching ahead
let loadedVolume = ""; // which volume `settings` were made for
let pendingFiducials: Vec3[] = [];
let mode: ClickMode = "navigate";
// The target or structure picked in the 3D view or clicked in its table: marked in both, and the
// slices go to it.
let selection: Selection = null;

// The server's clock, as far as what it published tells (clock.ts): approvals count down on it.
const serverClock = new ServerClock();
const localNow_s = () => performance.now() / 1000;

const panels = new Panels({
  goTo: (lps) => setCentre(lps),
  command: (kind, ids, path) => void command(kind, { ids, path: path ?? "" }),
  approve: (plan_id, digest) => ask("approve", { op: "approve", plan_id, digest }),
  serverNow_s: () => serverClock.now_s(localNow_s()),
});

const structuresPanel = new StructuresPanel({
  goTo: (lps) => setCentre(lps),
  command: (kind, args) => void command(kind, args),
});

// Whether a command from this page can reach the server now.
const connected = () => connectionView(socketStatus, serverConnected).connected;

const socket = new GatewaySocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`, {
  hello(message) {
    hello = message;
    byId("robot-id").textContent = message.robot_id;
    document.title = `ignav: ${message.robot_id}`;
    // A new connection: the slices are asked for again once the gateway says the server is there.
    scheduleRender();
  },
  state(topics) {
    const received_s = localNow_s();
    if (topics.health?.server_time_unix_s) serverClock.observe(topics.health.server_time_unix_s, received_s);
    if (topics.approval?.status === "pending") {
      const { expires_at_unix_s, expires_in_s } = topics.approval;
      serverClock.observe(approvalPublishedAt_s(expires_at_unix_s, expires_in_s), received_s);
    }
    state = { ...state, ...topics };
    if (topics.volume) volumeChanged();
    // The feasible region drawn in the slices follows the registration. (Without the server, the
    // slices are asked for once it is back.)
    if (topics.registration && connected()) for (const view of views) view.refresh(true);
    scheduleRender();
  },
  serverConnection(server) {
    const back = server && serverConnected !== true;
    serverConnected = server;
    // Whatever was asked while it was away (or on an older connection) is lost: ask again.
    // (The 3D view keeps its scene: it asks again only when the CT or what the surfaces are made
    // of changed, or a fetch failed.)
    if (back) for (const view of views) view.refresh(true);
    scheduleRender();
  },
  jobOutcome(outcome) {
    panels.jobOutcome(outcome);
  },
  status(status) {
    socketStatus = status;
    if (!status.open) serverConnected = null; // unknown until the gateway says again
    scheduleRender();
  },
});

// ---- requests ------------------------------------------------------------------------------

// Sends a request and shows its answer. Nothing but an emergency stop (whose button is disabled
// then anyway) is sent while the page cannot reach the server.
async function ask(what: string, request: Request): Promise<Answer> {
  const answer =
    connected() || request.op === "emergency_stop" ? await socket.request(request) : notConnected();
  panels.reply(what, answer);
  return answer;
}

function notConnected(): Answer {
  return { type: "error", seq: -1, code: "not_connected", message: "not sent: the server is not reachable from this page" };
}

function command(kind: string, args: { points?: Vec3[]; ids?: number[]; path?: string } = {}): Promise<Answer> {
  return ask(kind, { op: "command", kind, points: args.points ?? [], ids: args.ids ?? [], path: args.path ?? "" });
}

// ---- the views -----------------------------------------------------------------------------

function volumeChanged(): void {
  const volume = state.volume;
  const key = loadedVolumeKey(volume);
  if (key === loadedVolume) return;
  loadedVolume = key;
  // A new volume: look at all of it, from its middle.
  settings =
    volume && key
      ? {
          centre_lps: volumeCentre(volume.ijk_to_lps, volume.dims),
          pixel_mm: fittingPixelMm(volume.dims, volume.spacing_mm, kSizePx),
          window: Number(byId<HTMLInputElement>("window").value),
          level: Number(byId<HTMLInputElement>("level").value),
        }
      : null;
  pans = settings && centredPans(settings.centre_lps);
  for (const view of views) view.refresh(true);
  showCentre();
}

const centredPans = (lps: Vec3): Record<ViewName, Vec3> => ({ axial: lps, sagittal: lps, coronal: lps });

function changeSettings(change: Partial<ViewSettings>): void {
  if (!settings) return;
  settings = { ...settings, ...change };
  for (const view of views) view.refresh();
  showCentre();
  scheduleRender();
}

// Every view centred on `lps` (a click in navigate mode, "go to", a target's row).
function setCentre(lps: Vec3): void {
  if (!settings) return;
  pans = centredPans(lps);
  lastScroll = null;
  changeSettings({ centre_lps: lps });
}

// A wheel step on one view: the shared centre moves along that view's normal, at most to the
// volume's edge, and only that view asks for a slice; the others redraw their crosshair.
function scroll(name: ViewName, steps: number): void {
  const next = scrolledCentre(name, steps);
  if (!settings || !next) return;
  settings = { ...settings, centre_lps: next };
  lastScroll = { view: name, step: Math.sign(steps) };
  views.find((view) => view.name === name)?.refresh();
  showCentre();
  scheduleRender();
}

// The shared centre `steps` wheel steps along a view's normal, at most to the volume's edge.
function scrolledCentre(name: ViewName, steps: number): Vec3 | null {
  const volume = state.volume;
  if (!settings || !volume) return null;
  const normal = kViewNormal[name];
  const moved = add(settings.centre_lps, scale(normal, steps * spacingAlongNormal(normal)));
  return clampAlong(moved, normal, volume.ijk_to_lps, volume.dims);
}

// What one more step the way the view was scrolled last would show (the view fetches it ahead).
function prefetchSettings(name: ViewName): ViewSettings | null {
  if (!settings || !pans || lastScroll?.view !== name) return null;
  const next = scrolledCentre(name, lastScroll.step);
  return next && { ...settings, centre_lps: viewCentre(pans[name], next, kViewNormal[name]) };
}

// A view's settings: the shared ones, centred where that view is (viewCentre).
function viewSettings(name: ViewName): ViewSettings | null {
  if (!settings || !pans) return null;
  return { ...settings, centre_lps: viewCentre(pans[name], settings.centre_lps, kViewNormal[name]) };
}

function zoom(factor: number): void {
  if (settings) changeSettings({ pixel_mm: settings.pixel_mm * factor });
}

function showCentre(): void {
  byId("centre").textContent = settings ? formatLps(settings.centre_lps, 2) : "–";
}

// The spacing of the voxels along a view's normal: one wheel step, and the plane's thickness.
function spacingAlongNormal(normal: Vec3): number {
  const volume = state.volume;
  return volume ? spacingAlong(normal, volume.ijk_to_lps, volume.spacing_mm) : 1;
}

function overlay(): Overlay {
  const registration = state.registration;
  const phase = state.workflow?.phase ?? "";
  return {
    fiducials: registration?.status === "registered" ? registration.image_points : [],
    pending_fiducials: pendingFiducials,
    targets: Object.values(state.targets ?? {}).map((target) => {
      const shown = targetDisplay(target, phase, state.approval, state.motion);
      return {
        id: target.id,
        lps: target.lps,
        colour: shown.colour,
        tooltip: `${shown.label}: ${shown.detail}`,
        path_lps: target.path_lps ?? [],
      };
    }),
    tip_lps: state.motion?.tip_lps ?? null,
    seeds: seedMarkers(state.verification, state.registration, state.targets),
    proposals: state.structures?.proposed ?? [],
    placement: placementOverlay(),
    centre_lps: settings?.centre_lps ?? null,
  };
}

// The proposed placement (the best pose): its skin entry and its axis through the structure.
function placementOverlay(): Overlay["placement"] {
  const s = state.structures;
  const best = s?.placement_status === "placed" ? s.placements[0] : undefined;
  if (!best) return null;
  const structure = s?.structures.find((x) => x.name === s.placement_structure);
  return { entry_lps: best.entry_lps, axis_lps: placementAxis(best, structure?.bounds_lps) };
}

async function clickedFiducial(lps: Vec3): Promise<void> {
  if (pendingFiducials.length >= 3) return; // three are on their way
  pendingFiducials = [...pendingFiducials, lps];
  scheduleRender();
  if (pendingFiducials.length < 3) return;
  await command("set_fiducials", { points: pendingFiducials });
  // Accepted, they are the registration's now; rejected, the reply says why: click again.
  pendingFiducials = [];
  scheduleRender();
}

const host: ViewHost = {
  settings: viewSettings,
  prefetch: prefetchSettings,
  overlay,
  mode: () => mode,
  planeToleranceMm: (normal) => kPlaneToleranceVoxels * spacingAlongNormal(normal),
  send: (request) => socket.request(request),
  clicked(lps) {
    if (mode === "navigate") setCentre(lps);
    else if (!connected()) panels.reply(mode === "fiducial" ? "fiducial click" : "add_target", notConnected());
    else if (mode === "fiducial") void clickedFiducial(lps);
    else void command("add_target", { points: [lps] });
  },
  targetDragged(id, lps) {
    void command("move_target", { ids: [id], points: [lps] });
  },
  scrolled: scroll,
  zoomed: zoom,
};

const viewNames: ViewName[] = ["axial", "sagittal", "coronal"];
const views = viewNames.map((name) => new SliceView(name, byId("views"), host));

// The fourth view: the scene in 3D (issue 43).
const figure3d = document.createElement("figure");
figure3d.className = "view view3d";
byId("views").append(figure3d);
const view3d = new View3d(figure3d, {
  send: (request) => (connected() ? socket.request(request) : Promise.resolve(notConnected())),
  picked: (picked) => select(picked, true),
});

// Selects a target or a structure: its row marked (and scrolled to when the 3D view picked it),
// the slices centred on it, the 3D view's path or surface drawn stronger.
function select(picked: Selection, fromView: boolean): void {
  selection = picked;
  if (picked?.kind === "target") {
    const target = state.targets?.[String(picked.id)];
    if (target) setCentre(target.lps);
  } else if (picked?.kind === "structure") {
    const structure = state.structures?.structures.find((x) => x.name === picked.name);
    if (structure) setCentre(boundsCentre(structure.bounds_lps));
  }
  markSelection(fromView);
  scheduleRender();
}

function markSelection(scroll = false): void {
  const want = selection?.kind === "target" ? `target-row-${selection.id}` : selection?.kind === "structure" ? `structure-row-${selection.name}` : "";
  for (const row of document.querySelectorAll<HTMLElement>('tr[data-testid^="target-row-"], tr[data-testid^="structure-row-"]')) {
    const on = row.dataset.testid === want;
    row.classList.toggle("selected", on);
    row.setAttribute("aria-selected", String(on));
    if (on && scroll) row.scrollIntoView({ block: "nearest" });
  }
}

// A row's click selects it too (its own handler goes to it).
for (const [body, prefix] of [["targets-body", "target-row-"], ["structures-body", "structure-row-"]] as const) {
  byId(body).addEventListener("click", (event) => {
    const row = (event.target as HTMLElement).closest<HTMLElement>("tr");
    const id = row?.dataset.testid ?? "";
    if (!id.startsWith(prefix)) return;
    const name = id.slice(prefix.length);
    selection = prefix === "target-row-" ? { kind: "target", id: Number(name) } : { kind: "structure", name };
    markSelection();
    scheduleRender();
  });
}

// ---- rendering, at most once a frame -------------------------------------------------------

let renderScheduled = false;

function scheduleRender(): void {
  if (renderScheduled) return;
  renderScheduled = true;
  // A timer rather than requestAnimationFrame: a page in the background still follows.
  setTimeout(render, 16);
}

function render(): void {
  renderScheduled = false;
  panels.connection(socketStatus, serverConnected);
  panels.workflow(state.workflow, hello, state.motion);
  panels.volume(state.volume);
  panels.registration(state.registration, pendingFiducials);
  panels.targets(state.targets, state.workflow, state.approval, state.motion, state.verification, hello);
  structuresPanel.render(state.structures, panels.allowed(state.workflow, hello));
  panels.verification(state.verification);
  panels.approval(state.approval, hello);
  panels.motion(state.motion);
  for (const view of views) view.draw();
  markSelection();
  view3d.update({
    state,
    window: settings?.window ?? Number(byId<HTMLInputElement>("window").value),
    level: settings?.level ?? Number(byId<HTMLInputElement>("level").value),
    centre_lps: settings?.centre_lps ?? null,
    selection,
    targetColour: (target) => targetDisplay(target, state.workflow?.phase ?? "", state.approval, state.motion).colour,
    connected: connected(),
  });
}

// ---- controls ------------------------------------------------------------------------------

// Every button with data-command sends that command; it is enabled when the workflow allows it.
// data-path gives a fixed path, data-path-input the id of the field that holds one.
for (const button of document.querySelectorAll<HTMLButtonElement>("button[data-command]")) {
  button.addEventListener("click", () => {
    const { command: kind = "", path, pathInput } = button.dataset;
    const fromInput = pathInput ? byId<HTMLInputElement>(pathInput).value.trim() : undefined;
    void command(kind, { path: path ?? fromInput ?? "" });
  });
}

byId("estop").addEventListener("click", () => void ask("emergency_stop", { op: "emergency_stop" }));

for (const radio of document.querySelectorAll<HTMLInputElement>('input[name="mode"]')) {
  radio.addEventListener("change", () => {
    if (radio.checked) mode = radio.value as ClickMode;
  });
}

byId("clear-fiducials").addEventListener("click", () => {
  pendingFiducials = [];
  scheduleRender();
});

function goToFromField(): void {
  const lps = parseLps(byId<HTMLInputElement>("goto").value);
  byId("goto-error").textContent = lps ? "" : "expected x, y, z in mm (LPS)";
  if (lps) setCentre(lps);
}
byId("goto-button").addEventListener("click", goToFromField);
byId("goto").addEventListener("keydown", (event) => {
  if (event.key === "Enter") goToFromField();
});

function windowLevelFromFields(): void {
  changeSettings({
    window: Number(byId<HTMLInputElement>("window").value),
    level: Number(byId<HTMLInputElement>("level").value),
  });
}
for (const id of ["window", "level"]) byId(id).addEventListener("change", windowLevelFromFields);
for (const button of document.querySelectorAll<HTMLButtonElement>("button[data-preset]")) {
  button.addEventListener("click", () => {
    const [window, level] = kWindowPresets[button.dataset.preset ?? ""] ?? [0, 0];
    byId<HTMLInputElement>("window").value = String(window);
    byId<HTMLInputElement>("level").value = String(level);
    windowLevelFromFields();
  });
}

byId("zoom-in").addEventListener("click", () => zoom(1 / kZoomStep));
byId("zoom-out").addEventListener("click", () => zoom(kZoomStep));

setInterval(() => panels.tick(), 250); // the approval's countdown

// For tests and the curious: the state as the page holds it (a copy) and a way to drop the
// connection as a network failure would.
Object.defineProperty(window, "ignav", {
  value: Object.freeze({
    state: (): ServerState => structuredClone(state),
    hello: (): HelloMessage | null => structuredClone(hello),
    dropConnection: () => socket.drop(),
    // For benchmarks: whether a scrolled view fetches its next slice ahead (on by default).
    setPrefetching: (on: boolean) => {
      for (const view of views) view.prefetching = on;
    },
    // The 3D view: its camera and contents, and a turn of it (benchmarks).
    view3d: Object.freeze({
      describe: () => view3d.describe(),
      rotate: (degrees: number) => view3d.rotate(degrees),
      pickAt: (clientX: number, clientY: number) => view3d.pick(clientX, clientY),
      selection: (): Selection => structuredClone(selection),
    }),
  }),
});

render();
socket.start();
