// The web viewer (docs/WEB.md): the server's state as the gateway streams it, three slice views
// sharing one centre point, and the operator's workflow as clicks: fiducials, then targets,
// then lock, approve, watch. Every click is a command; the server decides and the reply shows.
import { add, fittingPixelMm, formatLps, parseLps, scale, spacingAlong, volumeCentre } from "./geometry";
import { Panels, byId } from "./panels";
import { GatewaySocket, type SocketStatus } from "./socket";
import type { Answer, HelloMessage, Request, ServerState, Vec3, ViewName } from "./state";
import { targetDisplay } from "./status";
import { type ClickMode, type Overlay, SliceView, type ViewHost, type ViewSettings, kSizePx } from "./views";

const kZoomStep = 1.25;
const kPlaneToleranceVoxels = 1.5; // a marker this near the plane is drawn on it
const kWindowPresets: Record<string, [number, number]> = { bone: [2000, 300], soft: [400, 40] };

// ---- what the page knows -------------------------------------------------------------------

let state: ServerState = {};
let hello: HelloMessage | null = null;
let socketStatus: SocketStatus = { open: false, retry_in_ms: 0 };
let serverConnected: boolean | null = null;
let settings: ViewSettings | null = null; // null until a volume is loaded
let loadedVolume = ""; // which volume `settings` were made for
let pendingFiducials: Vec3[] = [];
let mode: ClickMode = "navigate";

const panels = new Panels({
  goTo: (lps) => setCentre(lps),
  command: (kind, ids) => void command(kind, { ids }),
  approve: (plan_id, digest) => void ask("approve", { op: "approve", plan_id, digest }),
});

const socket = new GatewaySocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`, {
  hello(message) {
    hello = message;
    // A new connection: whatever was asked on the old one is lost.
    for (const view of views) view.refresh(true);
    scheduleRender();
  },
  state(topics) {
    state = { ...state, ...topics };
    if (topics.volume) volumeChanged();
    // The feasible region drawn in the slices follows the registration.
    if (topics.registration) for (const view of views) view.refresh(true);
    scheduleRender();
  },
  serverConnection(connected) {
    serverConnected = connected;
    scheduleRender();
  },
  status(status) {
    socketStatus = status;
    if (!status.open) serverConnected = null; // unknown until the gateway says again
    scheduleRender();
  },
});

// ---- requests ------------------------------------------------------------------------------

async function ask(what: string, request: Request): Promise<Answer> {
  const answer = await socket.request(request);
  panels.reply(what, answer);
  return answer;
}

function command(kind: string, args: { points?: Vec3[]; ids?: number[]; path?: string } = {}): Promise<Answer> {
  return ask(kind, { op: "command", kind, points: args.points ?? [], ids: args.ids ?? [], path: args.path ?? "" });
}

// ---- the views -----------------------------------------------------------------------------

function volumeChanged(): void {
  const volume = state.volume;
  const key = volume?.status === "loaded" ? JSON.stringify([volume.source, volume.dims, volume.ijk_to_lps]) : "";
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
  for (const view of views) view.refresh(true);
  showCentre();
}

function changeSettings(change: Partial<ViewSettings>): void {
  if (!settings) return;
  settings = { ...settings, ...change };
  for (const view of views) view.refresh();
  showCentre();
  scheduleRender();
}

function setCentre(lps: Vec3): void {
  changeSettings({ centre_lps: lps });
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
    centre_lps: settings?.centre_lps ?? null,
  };
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
  settings: () => settings,
  overlay,
  mode: () => mode,
  planeToleranceMm: (normal) => kPlaneToleranceVoxels * spacingAlongNormal(normal),
  send: (request) => socket.request(request),
  clicked(lps) {
    if (mode === "navigate") setCentre(lps);
    else if (mode === "fiducial") void clickedFiducial(lps);
    else void command("add_target", { points: [lps] });
  },
  targetDragged(id, lps) {
    void command("move_target", { ids: [id], points: [lps] });
  },
  scrolled(normal, steps) {
    if (settings) setCentre(add(settings.centre_lps, scale(normal, steps * spacingAlongNormal(normal))));
  },
  zoomed: zoom,
};

const viewNames: ViewName[] = ["axial", "sagittal", "coronal"];
const views = viewNames.map((name) => new SliceView(name, byId("views"), host));

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
  panels.workflow(state.workflow, hello);
  panels.volume(state.volume);
  panels.registration(state.registration, pendingFiducials);
  panels.targets(state.targets, state.workflow, state.approval, state.motion);
  panels.approval(state.approval, hello);
  panels.motion(state.motion);
  for (const view of views) view.draw();
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

setInterval(() => panels.tick(), 1000);

// For tests and the curious: the state as the page holds it (a copy) and a way to drop the
// connection as a network failure would.
Object.defineProperty(window, "ignav", {
  value: Object.freeze({
    state: (): ServerState => structuredClone(state),
    hello: (): HelloMessage | null => structuredClone(hello),
    dropConnection: () => socket.drop(),
  }),
});

render();
socket.start();
