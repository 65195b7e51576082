// The 3D view (issue 43; docs/WEB.md): the scene the server makes (the CT averaged down, the
// structures', feasible volume's and isodoses' surfaces) and what the state says (each target's
// planned path, the needle at the reported joints, the seeds found, the slice planes), drawn with
// vtk.js: Kitware's VTK for the browser, the pipeline 3D Slicer's own 3D view runs on (ray-cast
// volume rendering with transfer functions, polydata surfaces, tubes, a cell picker), so nothing
// here is hand-written WebGL. A click on a path, a target or a surface selects it in the panels;
// nothing of the workflow is decided here.
import "@kitware/vtk.js/Rendering/Profiles/Geometry";
import "@kitware/vtk.js/Rendering/Profiles/Volume";
import vtkDataArray from "@kitware/vtk.js/Common/Core/DataArray";
import vtkImageData from "@kitware/vtk.js/Common/DataModel/ImageData";
import vtkPiecewiseFunction from "@kitware/vtk.js/Common/DataModel/PiecewiseFunction";
import vtkPolyData from "@kitware/vtk.js/Common/DataModel/PolyData";
import vtkPolyDataNormals from "@kitware/vtk.js/Filters/Core/PolyDataNormals";
import vtkTubeFilter from "@kitware/vtk.js/Filters/General/TubeFilter";
import vtkSphereSource from "@kitware/vtk.js/Filters/Sources/SphereSource";
import vtkActor from "@kitware/vtk.js/Rendering/Core/Actor";
import vtkCellPicker from "@kitware/vtk.js/Rendering/Core/CellPicker";
import vtkColorTransferFunction from "@kitware/vtk.js/Rendering/Core/ColorTransferFunction";
import vtkMapper from "@kitware/vtk.js/Rendering/Core/Mapper";
import vtkVolume from "@kitware/vtk.js/Rendering/Core/Volume";
import vtkVolumeMapper from "@kitware/vtk.js/Rendering/Core/VolumeMapper";
import vtkGenericRenderWindow from "@kitware/vtk.js/Rendering/Misc/GenericRenderWindow";

import { invert, loadedVolumeKey, transformPoint, volumeBox } from "./geometry";
import {
  type StandardView,
  decodeBase64,
  imageGeometry,
  kStandardViews,
  littleEndian,
  polylineCells,
  slabsComplete,
  stripsToTriangles,
  structureOpacity,
  triangleCells,
  windowTransfer,
} from "./scene";
import type { Answer, SceneMessage, SceneRequest, ServerState, TargetState, Vec3 } from "./state";
import { seedMarkers } from "./verification";

export type Selection = { kind: "target"; id: number } | { kind: "structure"; name: string } | null;

export interface View3dHost {
  send(request: SceneRequest): Promise<Answer>;
  picked(selection: Selection): void; // a click on a path, a target or a structure's surface
}

// What the page shows that the 3D view follows.
export interface View3dInput {
  state: ServerState;
  window: number; // the slices' (HU)
  level: number;
  centre_lps: Vec3 | null; // the slices' crosshair
  selection: Selection;
  targetColour(target: TargetState): string; // CSS, as the table and the slices draw it
  connected: boolean;
}

export type CtMode = "volume" | "mip" | "off";
export type Layer = "structures" | "feasible" | "isodose" | "paths" | "needle" | "planes";

type Actor = ReturnType<typeof vtkActor.newInstance>;
type Picked = NonNullable<Selection>;

const kPathRadius_mm = 0.45;
const kSelectedPathRadius_mm = 0.9;
const kTargetRadius_mm = 1.5;
const kCannulaRadius_mm = 0.65;
const kStyletRadius_mm = 0.35;
const kSeedRadius_mm = 0.9;
const kClickSlop_px = 4; // a press that moves further is a rotation, not a click
// Without a GPU (WebGL in software: SwiftShader, llvmpipe) a frame of the CT takes hundreds of
// milliseconds of the page's thread, and the page's banners, emergency stop and countdown wait for
// a frame in progress: the view then draws half as many pixels each way (a quarter of the work).
const kSoftwareResolution = 0.5;
const kSoftwareRenderer = /swiftshader|llvmpipe|softpipe|software/i;

export class View3d {
  readonly container: HTMLElement;
  private readonly caption: HTMLElement;
  private readonly structureBoxes: HTMLElement; // a checkbox per structure's surface
  private readonly gw = vtkGenericRenderWindow.newInstance({ background: [0, 0, 0] });
  private readonly renderer;
  private readonly renderWindow;
  private readonly picker = vtkCellPicker.newInstance();
  private readonly volumeActor = vtkVolume.newInstance();
  private readonly volumeMapper = vtkVolumeMapper.newInstance();
  private volumeValues: { scale: number; offset: number } | null = null;
  // What is shown, each by the key of what it was made from: remade only when that changes.
  private volumeKey = ""; // the volume_id shown (or being fetched)
  private surfacesKey = "";
  private surfaceActors: Array<{ actor: Actor; kind: string; name: string }> = [];
  private pathsKey = "";
  private pathActors: Actor[] = [];
  private needleKey = "";
  private needleActors: Actor[] = [];
  private planesKey = "";
  private planeActors: Actor[] = [];
  private transferKey = "";
  private readonly pickedBy = new Map<Actor, Picked>();
  private ctMode: CtMode = "volume";
  private readonly layers = new Set<Layer>(["structures", "feasible", "isodose", "paths", "needle", "planes"]);
  private readonly hiddenStructures = new Set<string>();
  private cameraSet = false;
  private input: View3dInput | null = null;
  private fetchGeneration = 0;
  private framesRendered = 0;
  // Drawn only when something changed, at most once a frame: in software rendering (a machine
  // without a GPU) a frame of the CT takes a good part of a second.
  private dirty = false;
  private renderPending = false;
  private looksKey = "";
  private readonly renderMs: number[] = []; // the last frames' time on this thread
  // The last CT's fetch: its slabs received, then decoded, from its first request (ms).
  private volumeTimings: { received_ms: number; decoded_ms: number } | null = null;
  private resolution = 1; // of the canvas' pixels per CSS pixel (times devicePixelRatio)
  private readonly software: boolean; // WebGL without a GPU
  // When the CT and the surfaces were first drawn (ms since the page was opened), for benchmarks.
  private readonly drawnAt: { volume?: number; surfaces?: number } = {};
  private readonly awaitingDraw = new Set<"volume" | "surfaces">();
  private status = "no volume loaded";

  constructor(
    figure: HTMLElement,
    private readonly host: View3dHost,
  ) {
    this.container = document.createElement("div");
    this.container.className = "view3d-canvas";
    this.container.dataset.testid = "view-3d";
    this.caption = document.createElement("figcaption");
    this.caption.dataset.testid = "view-3d-status";
    this.structureBoxes = document.createElement("span");
    this.structureBoxes.className = "view3d-structures";
    figure.append(this.toolbar(), this.container, this.caption);
    this.gw.setContainer(this.container);
    this.gw.resize();
    this.renderer = this.gw.getRenderer();
    this.renderWindow = this.gw.getRenderWindow();
    const api = this.gw.getApiSpecificRenderWindow() as unknown as { getContext?(): WebGL2RenderingContext | null };
    this.software = kSoftwareRenderer.test(webglRenderer(api.getContext?.() ?? null));
    if (this.software) this.resolution = kSoftwareResolution;
    this.fitCanvas();
    this.volumeActor.setMapper(this.volumeMapper);
    this.volumeActor.getProperty().setInterpolationTypeToLinear();
    this.volumeActor.getProperty().setShade(false);
    this.picker.setPickFromList(true);
    this.picker.setTolerance(0);
    this.listen();
    new ResizeObserver(() => {
      this.fitCanvas();
      this.requestRender();
    }).observe(this.container);
    this.showStatus();
  }

  // The view's own controls: the standard views, how the CT is drawn, which layers show.
  private toolbar(): HTMLElement {
    const bar = document.createElement("div");
    bar.className = "view3d-toolbar";
    for (const view of Object.keys(kStandardViews) as StandardView[]) {
      const button = document.createElement("button");
      button.textContent = view;
      button.title = `look from ${kStandardViews[view].name} (and fit the scene)`;
      button.dataset.testid = `view3d-${view}`;
      button.addEventListener("click", () => this.standardView(view));
      bar.append(button);
    }
    const ct = document.createElement("select");
    ct.dataset.testid = "view3d-ct";
    ct.title = "the CT, through the slices' window: volume rendering, maximum-intensity projection, or none";
    for (const [value, text] of [["volume", "CT: volume"], ["mip", "CT: MIP"], ["off", "CT: off"]] as const) {
      const option = document.createElement("option");
      option.value = value;
      option.textContent = text;
      ct.append(option);
    }
    ct.addEventListener("change", () => this.setCtMode(ct.value as CtMode));
    bar.append(ct);
    const layers: Array<[Layer, string]> = [
      ["structures", "structures"], ["feasible", "feasible volume"], ["isodose", "isodoses"],
      ["paths", "paths"], ["needle", "needle & seeds"], ["planes", "slice planes"],
    ];
    for (const [layer, text] of layers) {
      const label = document.createElement("label");
      const box = document.createElement("input");
      box.type = "checkbox";
      box.checked = true;
      box.dataset.testid = `view3d-layer-${layer}`;
      box.addEventListener("change", () => this.setLayer(layer, box.checked));
      label.append(box, ` ${text}`);
      bar.append(label);
    }
    bar.append(this.structureBoxes);
    return bar;
  }

  // A checkbox per structure whose surface came, to show or hide it alone.
  private listStructures(): void {
    const names = this.surfaceActors.filter((s) => s.kind === "structure").map((s) => s.name);
    this.structureBoxes.replaceChildren(
      ...names.map((name) => {
        const label = document.createElement("label");
        const box = document.createElement("input");
        box.type = "checkbox";
        box.checked = !this.hiddenStructures.has(name);
        box.dataset.testid = `view3d-structure-${name}`;
        box.addEventListener("change", () => this.setStructureShown(name, box.checked));
        label.append(box, ` ${name}`);
        return label;
      }),
    );
  }

  // ---- what the page asks ----------------------------------------------------------------

  // Follows the state and the slices' settings: fetches what the server makes when what it is
  // made of changed, rebuilds what the state draws when it changed, then draws once.
  update(input: View3dInput): void {
    this.input = input;
    const s = input.state;
    const volumeKey = loadedVolumeKey(s.volume);
    const loaded = volumeKey !== "";
    if (volumeKey !== this.volumeKey && input.connected) {
      this.volumeKey = volumeKey;
      this.surfacesKey = "";
      void this.fetchVolume(volumeKey);
    }
    const surfacesKey = loaded
      ? JSON.stringify([
          volumeKey,
          s.structures?.source,
          s.structures?.structures.map((x) => [x.name, x.voxels]),
          s.registration?.status === "registered" ? s.registration.image_to_robot : null,
          s.robot?.config_path,
          s.structures?.dose_status,
          s.structures?.dose_message,
        ])
      : "";
    if (surfacesKey !== this.surfacesKey && input.connected) {
      this.surfacesKey = surfacesKey;
      void this.fetchSurfaces(surfacesKey);
    }
    this.updateTransfer();
    this.updatePaths();
    this.updateNeedle();
    this.updatePlanes();
    this.updateSurfaceLooks();
    if (this.dirty) this.requestRender();
  }

  standardView(view: StandardView): void {
    const { from, up } = kStandardViews[view];
    const camera = this.renderer.getActiveCamera();
    const focal = this.sceneCentre();
    camera.setFocalPoint(...focal);
    camera.setPosition(focal[0] + from[0], focal[1] + from[1], focal[2] + from[2]);
    camera.setViewUp(...up);
    this.renderer.resetCamera();
    this.renderer.resetCameraClippingRange();
    this.cameraSet = true;
    this.container.dataset.view = kStandardViews[view].name;
    this.render();
  }

  setCtMode(mode: CtMode): void {
    this.ctMode = mode;
    this.transferKey = "";
    this.updateTransfer();
    this.requestRender();
  }

  setLayer(layer: Layer, on: boolean): void {
    if (on) this.layers.add(layer);
    else this.layers.delete(layer);
    this.updateSurfaceLooks();
    for (const actor of this.pathActors) actor.setVisibility(this.layers.has("paths"));
    for (const actor of this.needleActors) actor.setVisibility(this.layers.has("needle"));
    for (const actor of this.planeActors) actor.setVisibility(this.layers.has("planes"));
    this.requestRender();
  }

  setStructureShown(name: string, on: boolean): void {
    if (on) this.hiddenStructures.delete(name);
    else this.hiddenStructures.add(name);
    this.updateSurfaceLooks();
    this.requestRender();
  }

  // Turns the camera about the view's up axis (for the benchmark's frames per second).
  rotate(degrees: number): void {
    this.renderer.getActiveCamera().azimuth(degrees);
    this.renderer.resetCameraClippingRange();
    this.render();
  }

  // For tests: the camera as vtk.js holds it, and what the view shows.
  describe(): object {
    const camera = this.renderer.getActiveCamera();
    const canvas = this.container.querySelector("canvas");
    return {
      status: this.status,
      position: camera.getPosition(),
      focal_point: camera.getFocalPoint(),
      view_up: camera.getViewUp(),
      view_angle_deg: camera.getViewAngle(),
      parallel: camera.getParallelProjection(),
      parallel_scale: camera.getParallelScale(),
      canvas_px: canvas ? [canvas.width, canvas.height] : [0, 0],
      css_px: [this.container.clientWidth, this.container.clientHeight],
      surfaces: this.surfaceActors.map((s) => ({ kind: s.kind, name: s.name, visible: s.actor.getVisibility() })),
      paths: this.pathActors.length,
      needle: this.needleActors.length,
      volume: this.volumeActor.getVisibility() && this.renderer.getVolumes().length > 0,
      frames: this.framesRendered,
      drawn_at_ms: { ...this.drawnAt },
      render_ms: [...this.renderMs],
      volume_timings: this.volumeTimings,
      resolution: this.resolution,
      software_rendering: this.software,
    };
  }

  // ---- the server's part of the scene ------------------------------------------------------

  private async fetchVolume(key: string): Promise<void> {
    const generation = ++this.fetchGeneration;
    this.renderer.removeVolume(this.volumeActor);
    this.volumeValues = null;
    this.cameraSet = false;
    if (!key) {
      this.setStatus("no volume loaded");
      return;
    }
    if (!littleEndian()) {
      this.setStatus("this machine is big-endian: the CT's numbers cannot be read");
      return;
    }
    const started = performance.now();
    // The first slab says how many slices a slab holds; the rest are asked for at once, so that
    // the server's, the gateway's and this page's work on successive slabs overlaps.
    const fail = (answer: Answer): boolean => {
      if (generation !== this.fetchGeneration) return true; // a newer volume is being fetched
      if (answer.type === "scene" && answer.ok) return false;
      this.volumeKey = ""; // asked again on the next update
      this.setStatus(`CT not shown: ${answer.type === "scene" || answer.type === "error" ? answer.message : "no answer"}`);
      return true;
    };
    const head = await this.host.send({ op: "scene", part: "volume", first_slice: 0 });
    if (fail(head) || head.type !== "scene") return;
    const slabs: SceneMessage[] = [head];
    let slicesReceived = head.slice_count;
    const rest: Array<Promise<Answer>> = [];
    for (let next = head.slice_count; head.slice_count > 0 && next < head.dims[2]; next += head.slice_count) {
      rest.push(
        this.host.send({ op: "scene", part: "volume", first_slice: next }).then((answer) => {
          if (answer.type === "scene" && answer.ok) {
            slicesReceived += answer.slice_count;
            this.setStatus(`CT: ${slicesReceived} of ${head.dims[2]} slices received`);
          }
          return answer;
        }),
      );
    }
    for (const answer of await Promise.all(rest)) {
      if (fail(answer) || answer.type !== "scene") return;
      // The CT changed while its slabs came: asked again on the next update.
      if (answer.volume_id !== head.volume_id) {
        this.volumeKey = "";
        return;
      }
      slabs.push(answer);
    }
    const first = slabs[0];
    if (!first || !slabsComplete(first.dims, slabs)) {
      this.volumeKey = "";
      this.setStatus("CT not shown: its slabs did not add up");
      return;
    }
    const received = performance.now();
    const [nx, ny, nz] = first.dims;
    const voxels = new Int16Array(nx * ny * nz);
    let offset = 0;
    for (const slab of slabs) {
      const part = new Int16Array(await decodeBase64(slab.voxels_base64));
      voxels.set(part, offset);
      offset += part.length;
    }
    if (generation !== this.fetchGeneration) return;
    this.volumeTimings = { received_ms: received - started, decoded_ms: performance.now() - started };
    const geometry = imageGeometry(first.ijk_to_lps);
    const image = vtkImageData.newInstance();
    image.setDimensions(nx, ny, nz);
    image.setOrigin(geometry.origin);
    image.setSpacing(geometry.spacing);
    image.setDirection(Float32Array.from(geometry.direction));
    image.getPointData().setScalars(vtkDataArray.newInstance({ name: "CT", numberOfComponents: 1, values: voxels }));
    this.volumeMapper.setInputData(image);
    this.volumeMapper.setSampleDistance(Math.min(...geometry.spacing) * 0.7);
    this.volumeValues = { scale: first.value_scale, offset: first.value_offset };
    this.transferKey = "";
    this.updateTransfer();
    this.renderer.addVolume(this.volumeActor);
    if (!this.cameraSet) this.standardView("A");
    this.setStatus(`CT ${nx} × ${ny} × ${nz} in ${((performance.now() - started) / 1000).toFixed(2)} s`);
    this.awaitingDraw.add("volume");
    this.requestRender();
  }

  private async fetchSurfaces(key: string): Promise<void> {
    if (!key) {
      this.replaceSurfaces([]);
      return;
    }
    const answer = await this.host.send({ op: "scene", part: "surfaces" });
    if (key !== this.surfacesKey) return; // something changed meanwhile: that fetch follows
    if (answer.type !== "scene" || !answer.ok) {
      this.surfacesKey = "";
      return;
    }
    const made: Array<{ actor: Actor; kind: string; name: string }> = [];
    for (const surface of answer.surfaces) {
      const points = new Float32Array(await decodeBase64(surface.points_base64));
      const triangles = new Uint32Array(await decodeBase64(surface.triangles_base64));
      const poly = vtkPolyData.newInstance();
      poly.getPoints().setData(points, 3);
      poly.getPolys().setData(triangleCells(triangles));
      // Made once and kept as data (the cell picker reads a mapper's own input).
      const normals = vtkPolyDataNormals.newInstance();
      normals.setInputData(poly);
      normals.update();
      const mapper = vtkMapper.newInstance({ scalarVisibility: false });
      mapper.setInputData(normals.getOutputData());
      const actor = vtkActor.newInstance();
      actor.setMapper(mapper);
      actor.getProperty().setColor(...surface.colour_rgb);
      made.push({ actor, kind: surface.kind, name: surface.name });
    }
    if (key !== this.surfacesKey) return;
    this.replaceSurfaces(made);
    if (made.length > 0) this.awaitingDraw.add("surfaces");
    if (!this.cameraSet && made.length > 0) this.standardView("A");
    this.requestRender();
  }

  private replaceSurfaces(made: Array<{ actor: Actor; kind: string; name: string }>): void {
    for (const old of this.surfaceActors) {
      this.renderer.removeActor(old.actor);
      this.pickedBy.delete(old.actor);
    }
    this.surfaceActors = made;
    this.looksKey = "";
    for (const s of made) {
      this.renderer.addActor(s.actor);
      if (s.kind === "structure") this.pickedBy.set(s.actor, { kind: "structure", name: s.name });
    }
    this.updateSurfaceLooks();
    this.listStructures();
  }

  // Each surface's visibility and opacity by its layer, its structure's role and the selection.
  private updateSurfaceLooks(): void {
    const input = this.input;
    const roles = new Map((input?.state.structures?.structures ?? []).map((x) => [x.name, x.role]));
    const selected = input?.selection?.kind === "structure" ? input.selection.name : null;
    const key = JSON.stringify([[...roles], selected, [...this.layers], [...this.hiddenStructures]]);
    if (key === this.looksKey) return;
    this.looksKey = key;
    this.dirty = true;
    for (const s of this.surfaceActors) {
      const property = s.actor.getProperty();
      if (s.kind === "structure") {
        s.actor.setVisibility(this.layers.has("structures") && !this.hiddenStructures.has(s.name));
        property.setOpacity(structureOpacity(roles.get(s.name) ?? "shown", s.name === selected));
      } else if (s.kind === "feasible") {
        s.actor.setVisibility(this.layers.has("feasible"));
        property.setOpacity(0.15);
      } else {
        s.actor.setVisibility(this.layers.has("isodose"));
        property.setOpacity(s.name.includes(" 100%") ? 0.45 : 0.2);
      }
    }
  }

  // ---- what the state draws ------------------------------------------------------------------

  private updateTransfer(): void {
    const input = this.input;
    if (!input || !this.volumeValues) return;
    const key = JSON.stringify([input.window, input.level, this.ctMode]);
    if (key === this.transferKey) return;
    this.transferKey = key;
    this.dirty = true;
    const { colour, opacity } = windowTransfer(input.window, input.level, this.volumeValues.scale, this.volumeValues.offset);
    const ctf = vtkColorTransferFunction.newInstance();
    for (const [value, grey] of colour) ctf.addRGBPoint(value, grey, grey, grey);
    const otf = vtkPiecewiseFunction.newInstance();
    if (this.ctMode === "mip") {
      // The brightest voxel along each ray, through the window: a radiograph of the window.
      otf.addPoint(colour[0]?.[0] ?? 0, 0);
      otf.addPoint(colour[1]?.[0] ?? 1, 1);
      this.volumeMapper.setBlendModeToMaximumIntensity();
    } else {
      for (const [value, alpha] of opacity) otf.addPoint(value, alpha);
      this.volumeMapper.setBlendModeToComposite();
    }
    const property = this.volumeActor.getProperty();
    property.setRGBTransferFunction(0, ctf);
    property.setScalarOpacity(0, otf);
    property.setScalarOpacityUnitDistance(0, 2.0);
    this.volumeActor.setVisibility(this.ctMode !== "off");
  }

  private updatePaths(): void {
    const input = this.input;
    if (!input) return;
    const targets = Object.values(input.state.targets ?? {});
    const selectedId = input.selection?.kind === "target" ? input.selection.id : null;
    const shown = targets.map((t) => [t.id, t.lps, t.path_lps ?? [], input.targetColour(t), t.id === selectedId]);
    const key = JSON.stringify(shown);
    if (key === this.pathsKey) return;
    this.pathsKey = key;
    this.dirty = true;
    for (const actor of this.pathActors) {
      this.renderer.removeActor(actor);
      this.pickedBy.delete(actor);
    }
    this.pathActors = [];
    for (const target of targets) {
      const colour = cssRgb(input.targetColour(target));
      const selected = target.id === selectedId;
      const marker = sphereActor(target.lps, selected ? 1.4 * kTargetRadius_mm : kTargetRadius_mm, colour);
      this.pathActors.push(marker);
      this.pickedBy.set(marker, { kind: "target", id: target.id });
      const path = target.path_lps ?? [];
      if (path.length >= 2) {
        const tube = tubeActor(path, selected ? kSelectedPathRadius_mm : kPathRadius_mm, colour);
        this.pathActors.push(tube);
        this.pickedBy.set(tube, { kind: "target", id: target.id });
      }
    }
    for (const actor of this.pathActors) {
      actor.setVisibility(this.layers.has("paths"));
      this.renderer.addActor(actor);
    }
  }

  // The needle at the reported joints (cannula and stylet), the confirmation CT's seeds and the
  // needle it found, on the planning CT.
  private updateNeedle(): void {
    const input = this.input;
    if (!input) return;
    const s = input.state;
    const needle = s.motion?.needle_lps ?? [];
    const seeds = this.seedsOnPlanningCt();
    const key = JSON.stringify([needle, seeds]);
    if (key === this.needleKey) return;
    this.needleKey = key;
    this.dirty = true;
    for (const actor of this.needleActors) this.renderer.removeActor(actor);
    this.needleActors = [];
    const [base, cannulaTip] = needle;
    if (base && cannulaTip) {
      this.needleActors.push(tubeActor([base, cannulaTip], kCannulaRadius_mm, [0.8, 0.82, 0.86]));
      if (needle.length >= 3) this.needleActors.push(tubeActor(needle.slice(1), kStyletRadius_mm, [1.0, 0.84, 0.3]));
    }
    for (const seed of seeds.points) this.needleActors.push(sphereActor(seed, kSeedRadius_mm, [1.0, 0.55, 0.0]));
    for (const path of seeds.paths) if (path.length >= 2) this.needleActors.push(tubeActor(path, kStyletRadius_mm, [1.0, 0.55, 0.0]));
    for (const actor of this.needleActors) {
      actor.setVisibility(this.layers.has("needle"));
      this.renderer.addActor(actor);
    }
  }

  // The confirmation CT's seeds on the planning CT as the slices draw them (seedMarkers), and the
  // needle it found (a tip's centreline, on the confirmation CT) carried there through the
  // confirmation CT's registration and the planning one's inverse (the robot frame is what both
  // scans share).
  private seedsOnPlanningCt(): { points: Vec3[]; paths: Vec3[][] } {
    const s = this.input?.state;
    const v = s?.verification;
    const points = seedMarkers(v, s?.registration, s?.targets).map((marker) => marker.lps);
    if (!v || (v.status !== "measured" && v.status !== "unmatched")) return { points, paths: [] };
    let toPlanning = (p: Vec3): Vec3 => p;
    if (s?.registration?.status === "registered" && v.image_to_robot.length === 16) {
      try {
        const robotToImage = invert(s.registration.image_to_robot);
        toPlanning = (p) => transformPoint(robotToImage, transformPoint(v.image_to_robot, p));
      } catch {
        // a singular registration: the confirmation CT's own LPS, as seedMarkers falls back to
      }
    }
    const tips = v.seeds.filter((seed) => !seed.rejected && seed.kind === "tip");
    return { points, paths: tips.map((seed) => (seed.path_lps ?? []).map(toPlanning)) };
  }

  // The three slice planes through the crosshair, across the CT, as outlines.
  private updatePlanes(): void {
    const input = this.input;
    const volume = input?.state.volume;
    if (!input || volume?.status !== "loaded" || !input.centre_lps) return;
    const key = JSON.stringify([input.centre_lps, volume.ijk_to_lps, volume.dims]);
    if (key === this.planesKey) return;
    this.planesKey = key;
    this.dirty = true;
    for (const actor of this.planeActors) this.renderer.removeActor(actor);
    this.planeActors = [];
    const [lo, hi] = volumeBox(volume.ijk_to_lps, volume.dims);
    const c = input.centre_lps;
    const outlines: Array<[Vec3[], [number, number, number]]> = [
      // axial (z), sagittal (x), coronal (y): each in the colour Slicer gives its view
      [[[lo[0], lo[1], c[2]], [hi[0], lo[1], c[2]], [hi[0], hi[1], c[2]], [lo[0], hi[1], c[2]], [lo[0], lo[1], c[2]]], [0.95, 0.3, 0.3]],
      [[[c[0], lo[1], lo[2]], [c[0], hi[1], lo[2]], [c[0], hi[1], hi[2]], [c[0], lo[1], hi[2]], [c[0], lo[1], lo[2]]], [0.95, 0.9, 0.3]],
      [[[lo[0], c[1], lo[2]], [hi[0], c[1], lo[2]], [hi[0], c[1], hi[2]], [lo[0], c[1], hi[2]], [lo[0], c[1], lo[2]]], [0.4, 0.8, 0.3]],
    ];
    for (const [points, colour] of outlines) {
      const actor = lineActor(points, colour);
      actor.setVisibility(this.layers.has("planes"));
      actor.setPickable(false);
      this.planeActors.push(actor);
      this.renderer.addActor(actor);
    }
  }

  // ---- picking ---------------------------------------------------------------------------------

  private listen(): void {
    let press: { x: number; y: number } | null = null;
    this.container.addEventListener("pointerdown", (event) => {
      press = { x: event.clientX, y: event.clientY };
    });
    this.container.addEventListener("pointerup", (event) => {
      const was = press;
      press = null;
      if (!was || Math.hypot(event.clientX - was.x, event.clientY - was.y) > kClickSlop_px) return;
      const picked = this.pick(event.clientX, event.clientY);
      if (picked) this.host.picked(picked);
    });
  }

  // What is nearest the eye under a point of the page (client pixels), among the visible paths,
  // targets and structures.
  pick(clientX: number, clientY: number): Picked | null {
    const canvas = this.container.querySelector("canvas");
    if (!canvas) return null;
    const rect = canvas.getBoundingClientRect();
    const x = ((clientX - rect.left) * canvas.width) / rect.width;
    const y = canvas.height - ((clientY - rect.top) * canvas.height) / rect.height;
    // Only what is shown: the picker keeps the nearest actor it hits, hidden or not.
    this.picker.initializePickList();
    for (const actor of this.pickedBy.keys()) if (actor.getVisibility()) this.picker.addPickList(actor);
    this.picker.pick([x, y, 0], this.renderer);
    const [nearest] = this.picker.getActors() as Actor[];
    return (nearest && this.pickedBy.get(nearest)) ?? null;
  }

  // ---- drawing ---------------------------------------------------------------------------------

  private sceneCentre(): Vec3 {
    const bounds = this.renderer.computeVisiblePropBounds();
    if (!bounds.every(Number.isFinite) || bounds[0] > bounds[1]) return [0, 0, 0];
    return [(bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2, (bounds[4] + bounds[5]) / 2];
  }

  private requestRender(): void {
    if (this.renderPending) return;
    this.renderPending = true;
    requestAnimationFrame(() => {
      this.renderPending = false;
      this.render();
    });
  }

  private render(): void {
    this.dirty = false;
    const started = performance.now();
    this.renderer.resetCameraClippingRange();
    this.renderWindow.render();
    this.renderMs.push(performance.now() - started);
    if (this.renderMs.length > 20) this.renderMs.shift();
    this.framesRendered++;
    for (const what of this.awaitingDraw) this.drawnAt[what] ??= performance.now();
    this.awaitingDraw.clear();
  }

  // The canvas' pixels: the box's, times the device's ratio and the resolution chosen.
  private fitCanvas(): void {
    const ratio = (window.devicePixelRatio || 1) * this.resolution;
    const width = Math.max(1, Math.floor(this.container.clientWidth * ratio));
    const height = Math.max(1, Math.floor(this.container.clientHeight * ratio));
    this.gw.getApiSpecificRenderWindow().setSize(width, height);
  }

  private setStatus(text: string): void {
    this.status = text;
    this.showStatus();
  }

  private showStatus(): void {
    this.caption.textContent = `3D · ${this.status}`;
  }
}

// ---- vtk.js pieces ---------------------------------------------------------------------------

function polyline(points: Vec3[]) {
  const poly = vtkPolyData.newInstance();
  poly.getPoints().setData(Float32Array.from(points.flat()), 3);
  poly.getLines().setData(polylineCells(points.length));
  return poly;
}

function tubeActor(points: Vec3[], radius_mm: number, colour: [number, number, number]): Actor {
  const tube = vtkTubeFilter.newInstance({ radius: radius_mm, numberOfSides: 12, capping: true });
  tube.setInputData(polyline(points));
  tube.update();
  // Its strips as triangles, so that a click picks it (stripsToTriangles).
  const made = tube.getOutputData();
  const caps = made.getPolys().getData() as Uint32Array;
  const sides = stripsToTriangles(made.getStrips().getData() as Uint32Array);
  const cells = new Uint32Array(caps.length + sides.length);
  cells.set(caps);
  cells.set(sides, caps.length);
  const poly = vtkPolyData.newInstance();
  poly.setPoints(made.getPoints());
  poly.getPolys().setData(cells);
  poly.getPointData().setNormals(made.getPointData().getNormals());
  const mapper = vtkMapper.newInstance({ scalarVisibility: false });
  mapper.setInputData(poly);
  const actor = vtkActor.newInstance();
  actor.setMapper(mapper);
  actor.getProperty().setColor(...colour);
  return actor;
}

function lineActor(points: Vec3[], colour: [number, number, number]): Actor {
  const mapper = vtkMapper.newInstance({ scalarVisibility: false });
  mapper.setInputData(polyline(points));
  const actor = vtkActor.newInstance();
  actor.setMapper(mapper);
  actor.getProperty().setColor(...colour);
  actor.getProperty().setLighting(false);
  return actor;
}

function sphereActor(centre: Vec3, radius_mm: number, colour: [number, number, number]): Actor {
  const source = vtkSphereSource.newInstance({ center: centre, radius: radius_mm, thetaResolution: 16, phiResolution: 12 });
  const mapper = vtkMapper.newInstance({ scalarVisibility: false });
  mapper.setInputConnection(source.getOutputPort());
  const actor = vtkActor.newInstance();
  actor.setMapper(mapper);
  actor.getProperty().setColor(...colour);
  return actor;
}

// The WebGL renderer's name ("ANGLE (Google, Vulkan 1.3.0 (SwiftShader Device …", "" unknown): of
// vtk.js's context, else of a context made to ask.
function webglRenderer(context: WebGL2RenderingContext | null): string {
  const gl = context ?? document.createElement("canvas").getContext("webgl2");
  if (!gl) return "";
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  return String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER) ?? "");
}

// "#00bcd4" as 0-1 channels (grey for anything else).
function cssRgb(css: string): [number, number, number] {
  const m = /^#([0-9a-f]{2})([0-9a-f]{2})([0-9a-f]{2})$/i.exec(css);
  if (!m) return [0.6, 0.6, 0.6];
  return [parseInt(m[1] ?? "99", 16) / 255, parseInt(m[2] ?? "99", 16) / 255, parseInt(m[3] ?? "99", 16) / 255];
}
