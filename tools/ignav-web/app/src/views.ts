// One slice view: a canvas showing the server's slice (the CT with the feasible region) and,
// drawn here, the fiducials, targets, planned paths and the needle tip. At most one slice request
// per view is in flight; when the wanted slice changes meanwhile, the newest is asked for once
// the answer is in (a scroll of ten steps costs two requests, not ten).
import {
  type CanvasScale,
  type SliceFrame,
  add,
  cssFromPixel,
  formatLps,
  pixelFromCss,
  pixelToLps,
  project,
  scale,
  sliceFrame,
  sub,
  norm,
} from "./geometry";
import type { Answer, SliceRequest, Vec3, ViewName } from "./state";

export const kSizePx = 512;

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
  centre_lps: Vec3 | null;
}

export type ClickMode = "navigate" | "fiducial" | "target";

// What a view needs from the page.
export interface ViewHost {
  settings(): ViewSettings | null; // null: no volume to show
  overlay(): Overlay;
  mode(): ClickMode;
  planeToleranceMm(normal: Vec3): number; // a point this close to the plane is on it
  send(request: SliceRequest): Promise<Answer>;
  clicked(lps: Vec3): void;
  targetDragged(id: number, lps: Vec3): void;
  scrolled(normal: Vec3, steps: number): void;
  zoomed(factor: number): void;
}

interface Shown {
  frame: SliceFrame;
  image: HTMLImageElement;
}

interface Drag {
  id: number;
  pointer: number;
  start_css: [number, number];
  u: number;
  v: number;
  moved: boolean;
}

const kMarkerRadiusPx = 7;
const kHitRadiusCss = 10; // how near a press must be to a marker to grab it
const kDragThresholdCss = 3; // a press that moves less is a click

export class SliceView {
  readonly canvas: HTMLCanvasElement;
  private readonly caption: HTMLElement;
  private readonly ctx: CanvasRenderingContext2D;
  private shown: Shown | null = null;
  private problem = ""; // why nothing is shown
  private lastRequest: string | null = null; // JSON of the request sent last
  private inFlight = false;
  private slicesShown = 0;
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

  // Ask for the slice the settings want, unless it is already shown or asked for. `force` asks
  // again even so: after a reconnection, a new volume or a new registration (the region).
  refresh(force = false): void {
    if (force) this.lastRequest = null;
    const settings = this.host.settings();
    if (!settings) {
      this.lastRequest = null;
      this.showNothing("no volume loaded");
      this.draw();
      return;
    }
    if (this.inFlight) return; // the answer's arrival calls refresh again
    const request: SliceRequest = {
      op: "slice",
      view: this.name,
      centre_lps: settings.centre_lps,
      size_px: kSizePx,
      pixel_mm: settings.pixel_mm,
      window: settings.window,
      level: settings.level,
      overlays: "region",
    };
    const key = JSON.stringify(request);
    if (key === this.lastRequest) return;
    this.lastRequest = key;
    this.inFlight = true;
    void this.host.send(request).then(async (answer) => {
      await this.show(answer, request);
      this.inFlight = false;
      // Lost with the connection: the next connection's hello asks again.
      if (answer.type === "error" && answer.code === "disconnected") return;
      this.refresh();
    });
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

  private async show(answer: Answer, request: SliceRequest): Promise<void> {
    if (answer.type === "error") {
      // Lost with the connection, the slice on screen stays until the next one. Otherwise, why.
      if (answer.code === "disconnected") {
        this.lastRequest = null;
        return;
      }
      this.showNothing(`${answer.code}: ${answer.message}`);
    } else if (answer.type !== "slice") {
      this.showNothing(`unexpected answer ${answer.type}`);
    } else if (!answer.ok) {
      this.showNothing(`slice: ${answer.message}`);
    } else {
      try {
        const image = new Image();
        image.src = `data:image/png;base64,${answer.png_base64}`;
        await image.decode();
        this.shown = { frame: sliceFrame(answer.pixel_to_lps), image };
        this.problem = "";
        // For tests and tools: the map of the slice on screen, and the centre it was asked for.
        this.canvas.dataset.pixelToLps = JSON.stringify(answer.pixel_to_lps);
        this.canvas.dataset.centreLps = JSON.stringify(request.centre_lps);
        this.canvas.dataset.slicesShown = String(++this.slicesShown);
        this.caption.textContent = `${this.name} · ${formatLps(request.centre_lps)} mm · ${request.pixel_mm.toFixed(3)} mm/px`;
      } catch (error) {
        this.showNothing(`slice: ${String(error)}`);
      }
    }
    this.draw();
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

    for (const target of overlay.targets) this.drawPath(frame, target.path_lps, target.colour, tolerance);

    overlay.fiducials.forEach((p, i) => this.marker(at(p), near(p), "#ffeb3b", `F${i + 1}`, "square"));
    overlay.pending_fiducials.forEach((p, i) => this.marker(at(p), near(p), "#ffeb3b", `F${i + 1}?`, "ring"));
    for (const target of overlay.targets) {
      const dragged = this.drag?.id === target.id && this.drag.moved;
      const position: readonly [number, number] = dragged && this.drag ? [this.drag.u, this.drag.v] : at(target.lps);
      this.marker(position, dragged || near(target.lps), target.colour, `T${target.id}`, "disc");
    }
    if (overlay.tip_lps) this.marker(at(overlay.tip_lps), near(overlay.tip_lps), "#ffffff", "tip", "cross");
  }

  // A polyline, solid where it runs within the tolerance of the plane and dashed and faint
  // elsewhere, in pieces of about one tolerance so that a crossing shows where it crosses.
  private drawPath(frame: SliceFrame, path: Vec3[], colour: string, tolerance: number): void {
    const ctx = this.ctx;
    ctx.strokeStyle = colour;
    ctx.lineWidth = 2;
    for (let i = 1; i < path.length; ++i) {
      const a = path[i - 1]!;
      const b = path[i]!;
      const step = sub(b, a);
      const pieces = Math.max(1, Math.ceil(norm(step) / tolerance));
      for (let k = 0; k < pieces; ++k) {
        const p = add(a, scale(step, k / pieces));
        const q = add(a, scale(step, (k + 1) / pieces));
        const mid = add(p, scale(sub(q, p), 0.5));
        const onPlane = Math.abs(project(frame, mid).distance_mm) <= tolerance;
        ctx.globalAlpha = onPlane ? 1 : 0.35;
        ctx.setLineDash(onPlane ? [] : [4, 4]);
        const pp = project(frame, p);
        const qq = project(frame, q);
        ctx.beginPath();
        ctx.moveTo(pp.u, pp.v);
        ctx.lineTo(qq.u, qq.v);
        ctx.stroke();
      }
    }
    ctx.globalAlpha = 1;
    ctx.setLineDash([]);
  }

  private marker(
    [u, v]: readonly [number, number],
    onPlane: boolean,
    colour: string,
    label: string,
    shape: "disc" | "ring" | "square" | "cross",
  ): void {
    const ctx = this.ctx;
    const r = onPlane ? kMarkerRadiusPx : kMarkerRadiusPx - 3;
    ctx.globalAlpha = onPlane ? 1 : 0.35;
    ctx.setLineDash([]);
    ctx.lineWidth = 2;
    ctx.strokeStyle = colour;
    ctx.fillStyle = colour;
    ctx.beginPath();
    switch (shape) {
      case "disc":
        ctx.arc(u, v, r, 0, 2 * Math.PI);
        ctx.fill();
        ctx.strokeStyle = "#000";
        ctx.lineWidth = 1;
        ctx.stroke();
        break;
      case "ring":
        ctx.setLineDash([3, 2]);
        ctx.arc(u, v, r, 0, 2 * Math.PI);
        ctx.stroke();
        break;
      case "square":
        ctx.rect(u - r, v - r, 2 * r, 2 * r);
        ctx.stroke();
        break;
      case "cross":
        ctx.moveTo(u - r, v - r);
        ctx.lineTo(u + r, v + r);
        ctx.moveTo(u - r, v + r);
        ctx.lineTo(u + r, v - r);
        ctx.stroke();
        break;
    }
    ctx.setLineDash([]);
    ctx.font = "bold 13px sans-serif";
    ctx.textAlign = "left";
    ctx.fillStyle = colour;
    ctx.strokeStyle = "#000";
    ctx.lineWidth = 3;
    ctx.strokeText(label, u + r + 3, v - r);
    ctx.fillText(label, u + r + 3, v - r);
    ctx.globalAlpha = 1;
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
      // The tooltip of the marker under the pointer: a target's verdict and the server's reason.
      const id = this.targetAt(shown.frame, css);
      const target = this.host.overlay().targets.find((t) => t.id === id);
      canvas.title = target ? `T${target.id}: ${target.tooltip}` : "";
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
        else this.host.scrolled(this.shown.frame.normal, event.deltaY > 0 ? 1 : -1);
      },
      { passive: false },
    );
  }
}
