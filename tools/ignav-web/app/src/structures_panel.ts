// The Structures panel and the two sections it feeds (issue 41): the patient's structures with
// their colours and roles (editable: structure_role), targets proposed to fill one or a seed plan
// for it (issue 42), accepted one by one or all at once, and where to mount the robot (the
// proposal, its alternatives, then the mounted robot against it). Rebuilt only when what it shows
// changes; the command buttons follow what the workflow allows and the gateway's identity may
// send, as every other button does.
import { ShownSlots, actionButton, byId, el } from "./dom";
import { formatLps } from "./geometry";
import type { StructureInfo, StructuresState, Vec3 } from "./state";
import {
  cssColour,
  kApproachSides,
  kRoles,
  placeCommand,
  placementLabel,
  progressText,
  proposeCommand,
  roleCommand,
  seedPlanCommand,
  structureChoices,
} from "./structures";

export interface StructuresActions {
  goTo(lps: Vec3): void;
  command(kind: string, args: { ids?: number[]; path?: string }): void;
}

export const boundsCentre = (b: number[]): Vec3 => [0, 1, 2].map((i) => (b[i]! + b[i + 3]!) / 2) as Vec3;
const percent = (x: number | null) => (x === null || !Number.isFinite(x) ? "–" : `${(100 * x).toFixed(1)} %`);

export class StructuresPanel {
  private readonly shown = new ShownSlots();

  constructor(private readonly actions: StructuresActions) {
    const side = byId<HTMLSelectElement>("placement-side");
    for (const name of kApproachSides) side.append(el("option", { value: name }, name));
    byId("propose").addEventListener("click", () => {
      const name = byId<HTMLSelectElement>("proposal-structure").value;
      const spacing_mm = Number(byId<HTMLInputElement>("proposal-spacing").value);
      this.actions.command("propose_targets", { path: proposeCommand(name, spacing_mm) });
    });
    // plan_seeds and compute_dose take the same words: the structure, a prescription and a
    // strength when given (blank: the site's, or the accepted plan's).
    const seedWords = () => {
      const number = (id: string) => {
        const text = byId<HTMLInputElement>(id).value.trim();
        return text === "" ? NaN : Number(text);
      };
      const name = byId<HTMLSelectElement>("proposal-structure").value;
      return seedPlanCommand(name, number("seed-rx"), number("seed-strength"));
    };
    byId("plan-seeds").addEventListener("click", () => this.actions.command("plan_seeds", { path: seedWords() }));
    byId("compute-dose").addEventListener("click", () => this.actions.command("compute_dose", { path: seedWords() }));
    byId("place").addEventListener("click", () => {
      const name = byId<HTMLSelectElement>("placement-structure").value;
      this.actions.command("place_robot", { path: placeCommand(name, side.value) });
    });
    byId("accept-all").addEventListener("click", () => this.actions.command("accept_proposals", { ids: [] }));
  }

  // `allowed`: the commands the workflow allows now and this page may send.
  render(structures: StructuresState | undefined, allowed: Set<string>): void {
    const s = structures;
    // A load that failed (or is under way) leaves the structures before in use: listed, usable.
    const names = structureChoices(s?.structures ?? []);
    byId<HTMLButtonElement>("propose").disabled = !allowed.has("propose_targets") || names.length === 0;
    byId<HTMLButtonElement>("plan-seeds").disabled = !allowed.has("plan_seeds") || names.length === 0;
    byId<HTMLButtonElement>("compute-dose").disabled = !allowed.has("compute_dose") || names.length === 0;
    byId<HTMLButtonElement>("place").disabled = !allowed.has("place_robot") || names.length === 0;
    byId<HTMLButtonElement>("accept-all").disabled = !allowed.has("accept_proposals") || !s?.proposed.length;
    if (this.shown.changed("choices", names)) {
      for (const id of ["proposal-structure", "placement-structure"]) fillChoices(byId<HTMLSelectElement>(id), names);
    }
    this.structures(s, allowed.has("structure_role"));
    this.proposals(s, allowed.has("accept_proposals"));
    this.placement(s);
    this.dose(s);
  }

  // The seeds' dose: a row per structure and dose (planned, delivered), the metrics its role is
  // judged by.
  private dose(s: StructuresState | undefined): void {
    if (!this.shown.changed("dose", [s?.dose_status, s?.dose_message, s?.dose])) return;
    const state = s?.dose_status ?? "none";
    const status = byId("dose-status");
    status.className = state === "failed" ? "bad" : "small";
    status.textContent = state === "none" || state === "" ? "no dose computed" : `${state}: ${s?.dose_message ?? ""}`;
    const value = (x: number | null, digits: number, unit: string) =>
      x === null || !Number.isFinite(x) ? "" : `${x.toFixed(digits)}${unit}`;
    const rows = (s?.dose ?? []).map((d) =>
      el(
        "tr",
        { "data-testid": `dose-row-${d.structure}-${d.which}` },
        el("td", { class: "name" }, d.structure),
        el("td", {}, d.which),
        el("td", { "data-testid": `dose-metrics-${d.structure}-${d.which}` },
          d.d90_percent !== null && Number.isFinite(d.d90_percent)
            ? `V100 ${percent(d.v100)}, D90 ${value(d.d90_percent, 1, " %")}, V150 ${percent(d.v150)}`
            : `D10 ${value(d.d10_percent, 1, " %")}, Dmax ${value(d.dmax_percent, 0, " %")}, D2cc ${value(d.d2cc_gy, 1, " Gy")}`),
      ),
    );
    byId("dose-body").replaceChildren(...rows);
  }

  private structures(s: StructuresState | undefined, canSetRole: boolean): void {
    if (!this.shown.changed("structures", [s?.status, s?.source, s?.message, s?.site, s?.structures, canSetRole])) return;
    const status = byId("structures-status");
    status.className = s?.status === "failed" ? "bad" : "small";
    // Loaded, the table says what the message lists (its notes too, in the tooltip); failed, why.
    status.textContent = !s || s.status === "none" || s.status === ""
      ? "no structures loaded"
      : s.status === "loading"
        ? `loading ${s.source}…`
        : `${s.status}: ${s.source}${s.site ? ` (site: ${s.site})` : ""}${s.status === "loaded" ? "" : `: ${s.message}`}`;
    status.title = s?.message ?? "";
    const rows = (s?.structures ?? []).map((x) => this.structureRow(x, canSetRole));
    byId("structures-body").replaceChildren(...rows);
  }

  private structureRow(x: StructureInfo, canSetRole: boolean): HTMLElement {
    const role = el("select", { "data-testid": `structure-role-${x.name}`, title: "target, avoid (with a margin), or shown only" });
    for (const name of kRoles) role.append(el("option", { value: name }, name));
    role.value = x.role;
    const margin = el("input", {
      "data-testid": `structure-margin-${x.name}`,
      type: "number", min: "0", max: "10", step: "0.5",
      value: String(x.margin_mm),
      title: "the margin in mm the needle's surface keeps (avoid)",
    });
    // Only avoid takes a margin.
    margin.disabled = x.role !== "avoid";
    role.addEventListener("change", () => (margin.disabled = role.value !== "avoid"));
    const stop = (event: Event) => event.stopPropagation(); // editing is not "go to"
    role.addEventListener("click", stop);
    margin.addEventListener("click", stop);
    const set = actionButton("set", `structure-set-${x.name}`, canSetRole, `give '${x.name}' this role`, () =>
      this.actions.command("structure_role", { path: roleCommand(x.name, role.value, Number(margin.value)) }),
    );
    const tr = el(
      "tr",
      {
        "data-testid": `structure-row-${x.name}`,
        title: `${x.name}: ${x.voxels} voxels, ${x.volume_cm3.toFixed(2)} cm³; click: go to its middle`,
      },
      el("td", {}, el("span", { class: "swatch", style: `background: ${cssColour(x.colour_rgb)}` })),
      el("td", { class: "name" }, x.name),
      el("td", {}, role),
      el("td", {}, margin),
      el("td", {}, set),
      el("td", { "data-testid": `structure-volume-${x.name}` }, `${x.volume_cm3.toFixed(1)} cm³`),
    );
    tr.addEventListener("click", () => this.actions.goTo(boundsCentre(x.bounds_lps)));
    return tr;
  }

  private proposals(s: StructuresState | undefined, canAccept: boolean): void {
    const fields = [
      s?.proposal_status, s?.proposal_message, s?.proposed, s?.proposal_progress_done,
      s?.proposal_progress_total, canAccept,
    ];
    if (!this.shown.changed("proposals", fields)) return;
    const status = byId("proposal-status");
    const state = s?.proposal_status ?? "none";
    status.className = state === "failed" ? "bad" : "small";
    const progress = progressText(s?.proposal_progress_done ?? 0, s?.proposal_progress_total ?? 0);
    status.textContent =
      state === "none" || state === "" ? "none proposed: Structures, Propose or Plan seeds"
        : state === "proposing" ? `${s?.proposal_message ?? "proposing"}…${progress ? ` ${progress}` : ""}`
          : `${state}: ${s?.proposal_message ?? ""}`;
    const bar = byId<HTMLProgressElement>("proposal-progress");
    bar.hidden = state !== "proposing";
    bar.max = Math.max(1, s?.proposal_progress_total ?? 1);
    bar.value = s?.proposal_progress_done ?? 0;
    const rows = (s?.proposed ?? []).map((p, index) => {
      const tr = el(
        "tr",
        { "data-testid": `proposal-row-${p.id}` },
        el("td", {}, String(index + 1)),
        el("td", {}, `P${p.id}`),
        el("td", { "data-testid": `proposal-lps-${p.id}` }, formatLps(p.lps)),
        el("td", { class: "actions" },
          actionButton("accept", `proposal-accept-${p.id}`, canAccept, `make P${p.id} a target`, () =>
            this.actions.command("accept_proposals", { ids: [p.id] }),
          ),
        ),
      );
      tr.addEventListener("click", () => this.actions.goTo(p.lps));
      return tr;
    });
    byId("proposals-body").replaceChildren(...rows);
  }

  private placement(s: StructuresState | undefined): void {
    const fields = s && [
      s.placement_status, s.placement_message, s.placement_structure, s.placement_progress_done,
      s.placement_progress_total, s.placements, s.mounted_status, s.mounted_message,
    ];
    if (!this.shown.changed("placement", fields)) return;
    const state = s?.placement_status ?? "none";
    const status = byId("placement-status");
    status.className = state === "failed" ? "bad" : "small";
    const progress = progressText(s?.placement_progress_done ?? 0, s?.placement_progress_total ?? 0);
    status.textContent =
      state === "none" || state === "" ? "none proposed: Structures, Place"
        : state === "placing" ? `placing the robot for '${s?.placement_structure}'…${progress ? ` ${progress}` : ""}`
          : `${state}: ${s?.placement_message ?? ""}`;
    const bar = byId<HTMLProgressElement>("placement-progress");
    bar.hidden = state !== "placing";
    bar.max = Math.max(1, s?.placement_progress_total ?? 1);
    bar.value = s?.placement_progress_done ?? 0;
    const rows = (s?.placements ?? []).map((p, index) => {
      const tr = el(
        "tr",
        { "data-testid": `placement-row-${index}`, title: "click: go to where the axis enters the skin" },
        el("td", {}, placementLabel(index)),
        el("td", { "data-testid": `placement-coverage-${index}` }, percent(p.coverage)),
        el("td", { "data-testid": `placement-entry-${index}` }, formatLps(p.entry_lps)),
        el("td", {}, p.axis_lps.map((x) => x.toFixed(3)).join(", ")),
        el("td", {}, p.tilt_deg.toFixed(1)),
        el("td", {}, p.shift_mm.toFixed(1)),
        el("td", { class: p.skin_seen ? "" : "warning", title: p.skin_seen ? "" : "no skin along the axis within the CT" },
          p.skin_seen ? p.skin_distance_mm.toFixed(1) : `${p.skin_distance_mm.toFixed(1)} (no skin seen)`),
      );
      tr.addEventListener("click", () => this.actions.goTo(p.entry_lps));
      return tr;
    });
    byId("placements-body").replaceChildren(...rows);
    const mounted = byId("mounted");
    const m = s?.mounted_status ?? "none";
    mounted.className = m === "failed" ? "bad" : "small";
    mounted.textContent =
      m === "measuring" ? "the mounted robot: measuring…"
        : m === "none" || m === "" ? ""
          : `the mounted robot: ${s?.mounted_message ?? ""}`;
  }
}

// A select's options, keeping what was chosen when it is still there.
function fillChoices(select: HTMLSelectElement, names: string[]): void {
  const chosen = select.value;
  select.replaceChildren(...names.map((name) => el("option", { value: name }, name)));
  if (names.includes(chosen)) select.value = chosen;
}
