// One slice view: a canvas showing the server's slice (the CT with the feasible region) and,
// drawn here, the fiducials, targets, planned paths, the needle tip and the seeds found on a
// confirmation CT (a red cross, joined to its target by a thin line). At most one slice request
// per view is in flight; when the wanted slice changes meanwhile, the newest is asked for once
// the answer is in (a scroll of ten steps costs two requests, not ten). Each view asks for its
// own slice only when its own plane or pan changes: scrolling one view asks for no other. While
// a view is being scrolled it fetches the next slice in that direction once the wanted one is
// shown, and keeps the last few slices, so that a step onto either is drawn without a wait.
import {
  type CanvasScale,
  type SliceFrame,
  cssFromPixel,
  formatLps,
  pixelFromCss,
  pixelToLps,
  project,
  sliceFrame,
} from "./geometry";
import type { Answer, SliceRequest, Vec3, ViewName } from "./state";
import { drawMarker, drawPath, drawSeeds } from "./overlay_drawing";
import { kPlacementColour, kProposalColour } from "./structures";
import type { SeedMarker } from "./verification";

export const kSizePx = 512;

// The unit normal n = u x v of each view's plane (modules/volume/include/ignav/volume/slice.hpp):
// axial +S, coronal +P, sagittal -L. A wheel step moves the plane along it.
export const kViewNormal: Record<ViewName, Vec3> = {
  axial: [0, 0, 1],
  coronal: [0, 1, 0],
  sagittal: [-1, 0, 0],
};

export interface ViewSettings {
  centre_lps: Vec3;
  pixel_mm: number;
  window: number;
  level: number;
}

export interface TargetMarker {
  id: number;
  lps: Vec3;
  colour: string;
  tooltip: string;
  path_lps: Vec3[];
}

// What is drawn over the slice, in LPS.
export interface Overlay {
  fiducials: Vec3[]; // registered, F1..F3
  pending_fiducials: Vec3[]; // clicked, not yet sent
  targets: TargetMarker[];
  tip_lps: Vec3 | null;
  seeds: SeedMarker[]; // on the planning CT (verification.ts)
  proposals: { id: number; lps: Vec3 }[]; // targets proposed to fill a structure (not yet accepted)
  placement: { entry_lps: Vec3; axis_lps: Vec3[] } | null; // where to mount the robot (its axis)
  centre_lps: Vec3 | null;
}

export type ClickMode = "navigate" | "fiducial" | "target";

// What a view needs from the page.
export interface ViewHost {
  settings(view: ViewName): ViewSettings | null; // this view's (its own centre); null: no volume
  overlay(): Overlay;
  mode(): ClickMode;
  planeToleranceMm(normal: Vec3): number; // a point this close to the plane is on it
  // The slice one more wheel step would want (this view was scrolled last), or null.
  prefetch(view: ViewName): ViewSettings | null;
  send(request: SliceRequest): Promise<Answer>;
  clicked(lps: Vec3): void;
  targetDragged(id: number, lps: Vec3): void;
  scrolled(view: ViewName, steps: number): void; // steps along kViewNormal[view]
  zoomed(factor: number): void;
}

interface Shown {
  frame: SliceFrame;
  image: HTMLImageElement;
  pixel_to_lps: number[];
  centre_lps: Vec3; // asked for
  pixel_mm: number;
}

interface Drag {
  id: number;
  pointer: number;
  start_css: [number, number];
  u: number;
  v: number;
  moved: boolean;
}

// Answers after which the view keeps its slice and waits to be asked again (on reconnection).
const kRetryLater = new Set(["disconnected", "no_server"]);

// Slices a view keeps (decoded, about 1 MB each): the last few shown and the one fetched ahead.
const kKeptSlices = 6;

const kHitRadiusCss = 10; // how near a press must be to a marker to grab it
const kDragThresholdCss = 3; // a press that moves less is a click

export class SliceView {
  readonly canvas: HTMLCanvasElement;
  private readonly caption: HTMLElement;
  private readonly ctx: CanvasRenderingContext2D;
  private shown: Shown | null = null;
  private problem = ""; // why nothing is shown
  // Slices are known by their request (JSON): the one on the canvas, the one the settings want,
  // the one asked for (at most one at a time), and the last ones received.
  private shownKey: string | null = null;
  private wantedKey: string | null = null;
  private fetchingKey: string | null = null;
  private prefetchedFor: string | null = null; // shownKey whose next slice was fetched ahead
  private readonly kept = new Map<string, Shown>(); // oldest first
  private generation = 0; // a forced refresh makes everything asked before it stale
  private slicesShown = 0;
  prefetching = true; // for benchmarks: off, every step waits for the server
  private drag: Drag | null = null;
  private press: { pointer: number; start_css: [number, number] } | null = null;

  constructor(
    readonly name: ViewName,
    container: HTMLElement,
    private readonly host: ViewHost,
  ) {
    const figure = document.createElement("figure");
    figure.className = "view";
    this.canvas = document.createElement("canvas");
    this.canvas.width = kSizePx;
    this.canvas.height = kSizePx;
    this.canvas.dataset.testid = `view-${name}`;
    this.canvas.dataset.view = name;
    this.caption = document.createElement("figcaption");
    figure.append(this.canvas, this.caption);
    container.append(figure);
    const ctx = this.canvas.getContext("2d");
    if (!ctx) throw new Error("no 2D canvas");
    this.ctx = ctx;
    this.listen();
    this.draw();
  }

  // Show the slice the settings want: at once when it is kept, else ask for it (unless another
  // request of this view is out: its answer calls refresh again). `force` forgets every slice
  // shown, kept or asked for: after a reconnection, a new volume or a new registration (the
  // region drawn in it).
  refresh(force = false): void {
    if (force) {
      this.generation++;
      this.shownKey = null;
      this.prefetchedFor = null;
      this.kept.clear();
    }
    const settings = this.host.settings(this.name);
    if (!settings) {
      this.shownKey = this.wantedKey = null;
      this.showNothing("no volume loaded");
      this.draw();
      return;
    }
    const request = this.request(settings);
    const key = JSON.stringify(request);
    this.wantedKey = key;
    if (key !== this.shownKey) {
      const kept = this.kept.get(key);
      if (kept) {
        this.display(key, kept);
      } else {
        if (this.fetchingKey === null) this.fetch(request, key);
        return;
      }
    }
    this.fetchAhead();
  }

  private request(settings: ViewSettings): SliceRequest {
    return {
      op: "slice",
      view: this.name,
      centre_lps: settings.centre_lps,
      size_px: kSizePx,
      pixel_mm: settings.pixel_mm,
      window: settings.window,
      level: settings.level,
      overlays: "region",
    };
  }

  private fetch(request: SliceRequest, key: string): void {
    this.fetchingKey = key;
    const generation = this.generation;
    void this.host.send(request).then(async (answer) => {
      const slice = await decode(answer, request);
      this.fetchingKey = null;
      if (generation !== this.generation) return this.refresh(); // asked before a forced refresh
      const wanted = key === this.wantedKey;
      if (typeof slice !== "string") {
        this.keep(key, slice);
      } else if (answer.type === "error" && kRetryLater.has(answer.code)) {
        // Lost with the connection or the server: the slice on screen stays (the banner says
        // why) and the view asks again once the server is back.
        return;
      } else if (wanted) {
        this.shownKey = key; // not asked again until something changes
        this.showNothing(slice);
        this.draw();
        return;
      } else {
        return; // a slice fetched ahead that failed: not asked again
      }
      this.refresh();
    });
  }

  // While this view is being scrolled: the slice one more step would show, fetched now.
  private fetchAhead(): void {
    if (!this.prefetching || this.fetchingKey !== null || this.shownKey === null) return;
    if (this.prefetchedFor === this.shownKey) return;
    const next = this.host.prefetch(this.name);
    if (!next) return;
    this.prefetchedFor = this.shownKey;
    const request = this.request(next);
    const key = JSON.stringify(request);
    if (!this.kept.has(key) && key !== this.shownKey) this.fetch(request, key);
  }

  private keep(key: string, slice: Shown): void {
    this.kept.delete(key);
    this.kept.set(key, slice);
    for (const oldest of this.kept.keys()) {
      if (this.kept.size <= kKeptSlices) break;
      this.kept.delete(oldest);
    }
  }

  private display(key: string, slice: Shown): void {
    this.keep(key, slice); // the most recently used
    this.shownKey = key;
    this.shown = slice;
    this.problem = "";
    // For tests and tools: the map of the slice on screen, and the centre it was asked for.
    this.canvas.dataset.pixelToLps = JSON.stringify(slice.pixel_to_lps);
    this.canvas.dataset.centreLps = JSON.stringify(slice.centre_lps);
    this.caption.textContent = `${this.name} · ${formatLps(slice.centre_lps)} mm · ${slice.pixel_mm.toFixed(3)} mm/px`;
    this.draw();
    // Counted once it is on the canvas (a test or bench waits for this to change).
    this.canvas.dataset.slicesShown = String(++this.slicesShown);
  }

  draw(): void {
    const ctx = this.ctx;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#000";
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    const shown = this.shown;
    if (!shown) {
      ctx.fillStyle = "#888";
      ctx.font = "16px sans-serif";
      ctx.textAlign = "center";
      ctx.fillText(this.problem || "waiting for the slice…", kSizePx / 2, kSizePx / 2);
      return;
    }
    ctx.drawImage(shown.image, 0, 0);
    // PNG pixel (u, v) has its centre at canvas (u + 0.5, v + 0.5).
    ctx.translate(0.5, 0.5);
    this.drawOverlay(shown.frame);
  }

  private showNothing(problem: string): void {
    this.shown = null;
    this.problem = problem;
    delete this.canvas.dataset.pixelToLps;
    delete this.canvas.dataset.centreLps;
  }

  private drawOverlay(frame: SliceFrame): void {
    const ctx = this.ctx;
    const overlay = this.host.overlay();
    const tolerance = this.host.planeToleranceMm(frame.normal);
    const near = (p: Vec3) => Math.abs(project(frame, p).distance_mm) <= tolerance;
    const at = (p: Vec3) => {
      const q = project(frame, p);
      return [q.u, q.v] as const;
    };

    if (overlay.centre_lps) {
      const [u, v] = at(overlay.centre_lps);
      ctx.strokeStyle = "rgba(255,255,0,0.5)";
      ctx.lineWidth = 1;
      ctx.setLineDash([]);
      for (const [du, dv] of [[1, 0], [-1, 0], [0, 1], [0, -1]] as const) {
        ctx.beginPath();
        ctx.moveTo(u + 6 * du, v + 6 * dv);
        ctx.lineTo(u + 18 * du, v + 18 * dv);
        ctx.stroke();
      }
    }

    // Beneath the plan: the proposed robot placement's axis and skin entry, and the proposed
    // targets on this plane (a lattice of up to 100 would hide the slice if all were drawn). Where
    // the entry was drawn is told to tests.
    if (overlay.placement) {
      const { entry_lps, axis_lps } = overlay.placement;
      drawPath(ctx, frame, axis_lps, kPlacementColour, tolerance);
      const [u, v] = at(entry_lps);
      drawMarker(ctx, [u, v], near(entry_lps), kPlacementColour, "entry", "square");
      this.canvas.dataset.placementEntry = JSON.stringify({ u, v, on_plane: near(entry_lps) });
    } else {
      delete this.canvas.dataset.placementEntry;
    }
    for (const p of overlay.proposals) if (near(p.lps)) drawMarker(ctx, at(p.lps), true, kProposalColour, `P${p.id}`, "ring");

    for (const target of overlay.targets) drawPath(ctx, frame, target.path_lps, target.colour, tolerance);

    overlay.fiducials.forEach((p, i) => drawMarker(ctx, at(p), near(p), "#ffeb3b", `F${i + 1}`, "square"));
    overlay.pending_fiducials.forEach((p, i) => drawMarker(ctx, at(p), near(p), "#ffeb3b", `F${i + 1}?`, "ring"));
    for (const target of overlay.targets) {
      const dragged = this.drag?.id === target.id && this.drag.moved;
      const position: readonly [number, number] = dragged && this.drag ? [this.drag.u, this.drag.v] : at(target.lps);
      drawMarker(ctx, position, dragged || near(target.lps), target.colour, `T${target.id}`, "disc");
    }
    if (overlay.tip_lps) drawMarker(ctx, at(overlay.tip_lps), near(overlay.tip_lps), "#ffffff", "tip", "cross");
    this.canvas.dataset.seeds = JSON.stringify(drawSeeds(ctx, overlay.seeds, at, near));
  }

  // ---- input ---------------------------------------------------------------------------

  private canvasScale(): CanvasScale {
    const rect = this.canvas.getBoundingClientRect();
    return { css_width: rect.width, css_height: rect.height, width_px: this.canvas.width, height_px: this.canvas.height };
  }

  private cssPosition(event: MouseEvent): [number, number] {
    const rect = this.canvas.getBoundingClientRect();
    return [event.clientX - rect.left, event.clientY - rect.top];
  }

  // The target marker under a CSS position, if any (only markers drawn on the plane).
  private targetAt(frame: SliceFrame, css: [number, number]): number | null {
    const s = this.canvasScale();
    const tolerance = this.host.planeToleranceMm(frame.normal);
    let best: number | null = null;
    let bestDistance = kHitRadiusCss;
    for (const target of this.host.overlay().targets) {
      const q = project(frame, target.lps);
      if (Math.abs(q.distance_mm) > tolerance) continue;
      const [x, y] = cssFromPixel(s, q.u, q.v);
      const d = Math.hypot(x - css[0], y - css[1]);
      if (d <= bestDistance) {
        bestDistance = d;
        best = target.id;
      }
    }
    return best;
  }

  // The seed marker under a CSS position, if any (only those drawn on the plane).
  private seedAt(frame: SliceFrame, css: [number, number]): SeedMarker | undefined {
    const s = this.canvasScale();
    const tolerance = this.host.planeToleranceMm(frame.normal);
    return this.host.overlay().seeds.find((seed) => {
      const q = project(frame, seed.lps);
      if (Math.abs(q.distance_mm) > tolerance) return false;
      const [x, y] = cssFromPixel(s, q.u, q.v);
      return Math.hypot(x - css[0], y - css[1]) <= kHitRadiusCss;
    });
  }

  private listen(): void {
    const canvas = this.canvas;
    canvas.addEventListener("pointerdown", (event) => {
      if (event.button !== 0 || !this.shown) return;
      const css = this.cssPosition(event);
      canvas.setPointerCapture(event.pointerId);
      const id = this.host.mode() === "target" ? this.targetAt(this.shown.frame, css) : null;
      if (id !== null) {
        const [u, v] = pixelFromCss(this.canvasScale(), css[0], css[1]);
        this.drag = { id, pointer: event.pointerId, start_css: css, u, v, moved: false };
      } else {
        this.press = { pointer: event.pointerId, start_css: css };
      }
    });
    canvas.addEventListener("pointermove", (event) => {
      const shown = this.shown;
      if (!shown) return;
      const css = this.cssPosition(event);
      const drag = this.drag;
      if (drag && drag.pointer === event.pointerId) {
        drag.moved ||= Math.hypot(css[0] - drag.start_css[0], css[1] - drag.start_css[1]) >= kDragThresholdCss;
        [drag.u, drag.v] = pixelFromCss(this.canvasScale(), css[0], css[1]);
        this.draw();
        return;
      }
      // The tooltip of the marker under the pointer: a target's verdict and the server's reason,
      // or a seed's target and error.
      const id = this.targetAt(shown.frame, css);
      const target = this.host.overlay().targets.find((t) => t.id === id);
      const seed = target ? undefined : this.seedAt(shown.frame, css);
      canvas.title = target
        ? `T${target.id}: ${target.tooltip}`
        : seed
          ? seed.target_id
            ? `seed S${seed.seed_id} of T${seed.target_id}: error ${seed.error_mm?.toFixed(2) ?? "?"} mm`
            : `seed S${seed.seed_id}: matched to no target`
          : "";
    });
    canvas.addEventListener("pointerup", (event) => {
      const shown = this.shown;
      const css = this.cssPosition(event);
      const [u, v] = pixelFromCss(this.canvasScale(), css[0], css[1]);
      const drag = this.drag;
      const press = this.press;
      this.drag = null;
      this.press = null;
      if (!shown) return;
      if (drag && drag.pointer === event.pointerId) {
        if (drag.moved) this.host.targetDragged(drag.id, pixelToLps(shown.frame, u, v));
        this.draw();
      } else if (press && press.pointer === event.pointerId) {
        if (Math.hypot(css[0] - press.start_css[0], css[1] - press.start_css[1]) < kDragThresholdCss) {
          this.host.clicked(pixelToLps(shown.frame, u, v));
        }
      }
    });
    canvas.addEventListener("pointercancel", () => {
      this.drag = null;
      this.press = null;
      this.draw();
    });
    canvas.addEventListener(
      "wheel",
      (event) => {
        if (!this.shown || event.deltaY === 0) return;
        event.preventDefault();
        if (event.ctrlKey) this.host.zoomed(event.deltaY > 0 ? 1.25 : 1 / 1.25);
        else this.host.scrolled(this.name, event.deltaY > 0 ? 1 : -1);
      },
      { passive: false },
    );
  }
}

// A slice answer decoded for the canvas, or why there is none.
async function decode(answer: Answer, request: SliceRequest): Promise<Shown | string> {
  if (answer.type === "error") return `${answer.code}: ${answer.message}`;
  if (answer.type !== "slice") return `unexpected answer ${answer.type}`;
  if (!answer.ok) return `slice: ${answer.message}`;
  try {
    const image = new Image();
    image.src = `data:image/png;base64,${answer.png_base64}`;
    await image.decode();
    return {
      frame: sliceFrame(answer.pixel_to_lps),
      image,
      pixel_to_lps: answer.pixel_to_lps,
      centre_lps: request.centre_lps,
      pixel_mm: request.pixel_mm,
    };
  } catch (error) {
    return `slice: ${String(error)}`;
  }
}
