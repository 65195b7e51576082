// The panels around the slice views: connection, workflow, volume, registration, targets,
// approval, motion, the targeting error measured on a confirmation CT and the last reply. Each is
// rebuilt only when what it shows has changed, so that a stream of motion updates neither
// flickers the table nor swallows a click on it. While the page cannot reach the server, a banner
// says so and every control that would send a command is disabled, the emergency stop included
// (alerts.ts).
import { connectionView, phaseBanner } from "./alerts";
import { approvalView } from "./approval";
import { ShownSlots, actionButton, byId, el, facts } from "./dom";
import { formatLps } from "./geometry";
import type { SocketStatus } from "./socket";
import type {
  Answer,
  ApprovalState,
  HelloMessage,
  JobOutcomeMessage,
  MotionState,
  RegistrationState,
  MeasuredTargetState,
  TargetState,
  Vec3,
  VerificationState,
  VolumeState,
  WorkflowState,
} from "./state";
import { jobOutcomeText, jobStartedText, replyText, targetDisplay, withinReach } from "./status";
import { clearanceCell } from "./structures";
import { extremes, fixed, meanSd, measuredByTarget, registrationText, withSe } from "./verification";

export interface PanelActions {
  goTo(lps: Vec3): void;
  command(kind: string, ids: number[], path?: string): void;
  approve(plan_id: number, digest: string): Promise<Answer>;
  serverNow_s(): number | null; // the page's estimate of the server's clock (clock.ts)
}

const kDegPerRad = 180 / Math.PI;

const mm = (x: number, digits = 2) => `${x.toFixed(digits)} mm`;

const approvalKey = (a: ApprovalState) => `${a.plan_id}:${a.digest}`;

const formatRobot = (p: Vec3) => `(${p.map((x) => fixed(x, 2)).join(", ")})`;

// How the target is aimed: nominal, or compensated for a tissue's deflection (use_tissue).
function aimCell(target: TargetState): HTMLElement {
  const testid = { "data-testid": `target-aim-${target.id}` };
  if (target.compensated === undefined) return el("td", testid, "–"); // a server before issue 23
  if (!target.compensated) return el("td", { ...testid, title: "the nominal joints (no tissue model)" }, "nominal");
  const [theta_c_rad, z_c_mm, z_s_mm] = target.nominal_joints ?? [0, 0, 0];
  const title =
    `aimed so that ${target.aim_tissue ?? "?"}'s model lands the tip on the target; nominal joints ` +
    `θc ${(theta_c_rad * kDegPerRad).toFixed(1)}°, zc ${fixed(z_c_mm, 2)}, zs ${fixed(z_s_mm, 2)} mm` +
    (target.nominal_landing_robot ? ` would land at ${formatRobot(target.nominal_landing_robot)}` : "") +
    (target.predicted_landing_robot ? `; these land at ${formatRobot(target.predicted_landing_robot)} (robot, mm)` : "");
  return el("td", { ...testid, class: "compensated", title }, `compensated: ${target.aim_tissue ?? "?"}`);
}

// The targeting error measured on the confirmation CT: its norm, the seed and the split in the
// tooltip; "no seed" for a reached target without one.
function errorCell(id: number, row: MeasuredTargetState | undefined, missing: boolean): HTMLElement {
  const testid = `target-error-${id}`;
  if (row) {
    const title =
      `seed S${row.seed_id} (${row.matched}): lateral ${fixed(row.lateral_mm, 2)} mm, ` +
      `depth ${fixed(row.depth_mm, 2, true)} mm (+ deeper than planned); error ${formatRobot(row.error_robot)} mm (robot)`;
    return el("td", { "data-testid": testid, title }, fixed(row.error_mm, 2));
  }
  if (missing) return el("td", { "data-testid": testid, class: "warning", title: "reached, and no seed found" }, "no seed");
  return el("td", { "data-testid": testid }, "–");
}

// The avoided structure with the least room (structures.ts), the list and any override in its
// tooltip; too close shows as a warning until an operator overrides it.
function clearanceTd(target: TargetState): HTMLElement {
  const cell = clearanceCell(target);
  const kind = cell.too_close ? "clearance warning" : cell.overridden ? "clearance overridden" : "clearance";
  return el("td", { "data-testid": `target-clearance-${target.id}`, class: kind, title: cell.title }, cell.text);
}

export class Panels {
  private readonly shown = new ShownSlots();
  private replies = 0;
  private connected = false; // commands from this page reach the server
  private pending: { approval: ApprovalState; may_approve: boolean } | null = null;
  private approving: string | null = null; // approvalKey of the approval on its way

  constructor(private readonly actions: PanelActions) {}

  // Whether the page reaches the server; the other panels follow what this last said.
  connection(status: SocketStatus, server: boolean | null): void {
    const view = connectionView(status, server);
    this.connected = view.connected;
    const element = byId("connection");
    element.textContent = view.header;
    element.className = view.connected ? "ok" : "bad";
    const banner = byId("connection-banner");
    banner.textContent = view.banner ?? "";
    banner.hidden = view.banner === null;
    // Not a button that looks active and does nothing: it says it cannot reach the robot.
    const estop = byId<HTMLButtonElement>("estop");
    estop.disabled = !view.connected;
    estop.classList.toggle("unreachable", !view.connected);
    estop.textContent = view.connected ? "EMERGENCY STOP" : "E-STOP NOT REACHABLE FROM THIS PAGE";
    estop.title = view.connected
      ? "halts the robot from any phase"
      : "this page cannot reach the server: use the robot's hardware emergency stop or another station";
  }

  // A button is enabled when the page reaches the server, the workflow allows its command now
  // and the gateway's identity may send it at all (a viewer's gateway shows the plan but cannot
  // change it).
  allowed(workflow: WorkflowState | undefined, hello: HelloMessage | null): Set<string> {
    const permitted = new Set(this.connected ? (hello?.permitted ?? []) : []);
    return new Set((workflow?.allowed_commands ?? []).filter((c) => permitted.has(c)));
  }

  workflow(workflow: WorkflowState | undefined, hello: HelloMessage | null, motion: MotionState | undefined): void {
    const allowed = this.allowed(workflow, hello);
    byId("phase").textContent = workflow?.phase ?? "";
    byId("phase").dataset.phase = workflow?.phase ?? "";
    byId("allowed").textContent = workflow ? workflow.allowed_commands.join(", ") : "";
    byId("last-event").textContent = workflow?.last_event ?? "";
    // A safeguard the site weakened (motion approval over OpenIGTLink): said where it is seen.
    const notice = byId("safety-notice");
    notice.textContent = workflow?.safety_notice ?? "";
    notice.hidden = !workflow?.safety_notice;
    const halted = phaseBanner(workflow?.phase ?? "", motion?.fault ?? "");
    const banner = byId("phase-banner");
    banner.textContent = halted ?? "";
    banner.hidden = halted === null;
    for (const button of document.querySelectorAll<HTMLButtonElement>("button[data-command]")) {
      button.disabled = !allowed.has(button.dataset.command ?? "");
    }
  }

  volume(volume: VolumeState | undefined): void {
    if (!this.shown.changed("volume", volume)) return;
    const body = byId("volume-body");
    if (!volume) {
      body.replaceChildren("no volume state yet");
      return;
    }
    const [done, total] = volume.progress;
    body.replaceChildren(
      facts([
        ["status", volume.status, "volume-status"],
        ["progress", total > 0 ? `${done} / ${total} files` : "–"],
        ["source", volume.source || "–"],
        ["size", `${volume.dims.join(" × ")} voxels, ${volume.spacing_mm.map((s) => s.toFixed(2)).join(" × ")} mm`],
        ["message", volume.message || "–", "volume-message"],
      ]),
    );
  }

  registration(registration: RegistrationState | undefined, pending: Vec3[]): void {
    if (this.shown.changed("registration", registration)) {
      const body = byId("registration-body");
      if (!registration) {
        body.replaceChildren("no registration state yet");
      } else {
        const registered = registration.status === "registered";
        body.replaceChildren(
          facts([
            ["status", registration.status + (registration.auto_detected ? " (auto-detected)" : ""), "registration-status"],
            ["kind", registration.kind || "–"],
            ["FRE", registered ? mm(registration.fre_mm, 3) : "–", "fre"],
            ["residuals", registered ? registration.residuals_mm.map((r) => r.toFixed(3)).join(", ") + " mm" : "–"],
            ["scale", registered ? registration.scale.toFixed(4) : "–"],
            ["message", registration.message || "–", "registration-message"],
          ]),
        );
      }
    }
    if (this.shown.changed("pending-fiducials", pending)) {
      byId("pending-fiducials").replaceChildren(
        ...pending.map((p, i) => el("li", {}, `F${i + 1}: ${formatLps(p)}`)),
      );
    }
  }

  targets(
    targets: Record<string, TargetState> | undefined,
    workflow: WorkflowState | undefined,
    approval: ApprovalState | undefined,
    motion: MotionState | undefined,
    verification: VerificationState | undefined,
    hello: HelloMessage | null,
  ): void {
    const phase = workflow?.phase ?? "";
    // As the workflow buttons: allowed now, and permitted to this gateway's identity at all.
    const allowed = [...this.allowed(workflow, hello)];
    // Motion matters to the table only as "which target is it moving to".
    const moving = motion ? { state: motion.state, target_id: motion.target_id } : undefined;
    const pending = approval ? { status: approval.status, target_id: approval.target_id } : undefined;
    // The confirmation CT matters as each target's measured row and the targets without a seed.
    const measured = measuredByTarget(verification);
    const missing = new Set(verification?.status === "measured" ? verification.missing_targets : []);
    if (!this.shown.changed("targets", [targets, phase, allowed, moving, pending, [...measured.values()], [...missing]])) return;

    const list = Object.values(targets ?? {}).sort((a, b) => a.order - b.order || a.id - b.id);
    const canReorder = allowed.includes("reorder_targets");
    const canRemove = allowed.includes("remove_target");
    const canAccept = allowed.includes("accept_seed");
    const canReject = allowed.includes("reject_seed");
    const canOverride = allowed.includes("override_clearance");
    const rows = list.map((target, index) => {
      const shown = targetDisplay(target, phase, approval, motion);
      const [theta_c_rad, z_c_mm, z_s_mm] = target.joints;
      const known = withinReach(target);
      const row = measured.get(target.id);
      const reorder = (offset: number) => {
        const ids = list.map((t) => t.id);
        [ids[index], ids[index + offset]] = [ids[index + offset]!, ids[index]!];
        this.actions.command("reorder_targets", ids);
      };
      const seedButtons = row
        ? [
            actionButton(`✓S${row.seed_id}`, `target-accept-seed-${target.id}`, canAccept && row.matched === "detected",
              `accept: S${row.seed_id} is T${target.id}'s seed (keep the pair)`, () =>
                this.actions.command("accept_seed", [target.id]),
            ),
            actionButton(`✗S${row.seed_id}`, `target-reject-seed-${target.id}`, canReject,
              `reject: S${row.seed_id} is no seed of this plan (match again without it)`, () =>
                this.actions.command("reject_seed", [row.seed_id]),
            ),
          ]
        : [];
      const tr = el(
        "tr",
        { "data-testid": `target-row-${target.id}`, title: `T${target.id}: ${shown.detail}` },
        el("td", {}, String(target.order)),
        el("td", {}, `T${target.id}`),
        el("td", {}, formatLps(target.lps)),
        el("td", { "data-testid": `target-status-${target.id}`, style: `color: ${shown.colour}` }, shown.label),
        el(
          "td",
          { "data-testid": `target-reach-${target.id}`, class: shown.path_warning ? "reason warning" : "reason" },
          shown.detail,
        ),
        el("td", {}, known ? (theta_c_rad * kDegPerRad).toFixed(1) : "–"),
        el("td", {}, known ? z_c_mm.toFixed(2) : "–"),
        el("td", {}, known ? z_s_mm.toFixed(2) : "–"),
        el("td", {}, known ? target.steps.join(", ") : "–"),
        el("td", { class: target.tre_warning ? "warning" : "" }, target.registered ? target.tre_mm.toFixed(2) : "–"),
        el("td", {}, target.predicted_deviation_mm === null ? "–" : target.predicted_deviation_mm.toFixed(2)),
        clearanceTd(target),
        aimCell(target),
        errorCell(target.id, row, missing.has(target.id)),
        el(
          "td",
          { "data-testid": `target-predicted-${target.id}`, title: "the model's landing, off the plan" },
          row?.predicted_robot ? fixed(row.predicted_error_mm, 2) : "–",
        ),
        el(
          "td",
          { class: "actions" },
          actionButton("↑", `target-up-${target.id}`, canReorder && index > 0, "earlier", () => reorder(-1)),
          actionButton("↓", `target-down-${target.id}`, canReorder && index < list.length - 1, "later", () => reorder(1)),
          actionButton("✕", `target-delete-${target.id}`, canRemove, "delete", () =>
            this.actions.command("remove_target", [target.id]),
          ),
          ...seedButtons,
          ...(target.clearance_refusal && !target.clearance_override
            ? [
                actionButton("override", `target-override-${target.id}`, canOverride,
                  `plan T${target.id} although its needle passes so close, for the reason written below the table`, () =>
                    this.actions.command("override_clearance", [target.id], byId<HTMLInputElement>("override-reason").value),
                ),
              ]
            : []),
        ),
      );
      tr.addEventListener("click", () => this.actions.goTo(target.lps));
      return tr;
    });
    byId("targets-body").replaceChildren(...rows);
    byId("targets-empty").hidden = rows.length > 0;
  }

  approval(current: ApprovalState | undefined, hello: HelloMessage | null): void {
    const waiting = current?.status === "pending" ? current : undefined;
    // An approval on its way is for the request it was clicked on; any other request is new.
    if (this.approving !== null && (!waiting || approvalKey(waiting) !== this.approving)) this.approving = null;
    if (!this.shown.changed("approval", [current, hello])) return this.tick();
    const body = byId("approval-body");
    const approve = byId<HTMLButtonElement>("approve");
    if (!waiting) {
      body.replaceChildren(el("p", { "data-testid": "approval-none" }, "no motion waits for approval"));
      this.pending = null;
      approve.onclick = null;
      return this.tick();
    }
    const approval = waiting;
    const identity = [hello?.client_id, hello?.subject].filter((x): x is string => !!x);
    const mayApprove =
      (hello?.permitted ?? []).includes("approve") && identity.some((who) => approval.approvers.includes(who));
    body.replaceChildren(
      el("pre", { "data-testid": "approval-summary" }, approval.summary),
      facts([
        ["plan", String(approval.plan_id), "approval-plan"],
        ["target", approval.target_id === 0 ? "final retraction" : `T${approval.target_id}`],
        ["digest", `${approval.digest.slice(0, 12)}…`, "approval-digest", approval.digest],
        ["moves", approval.moves.map((m) => `${m.kind} ${m.steps.join("/")}`).join("; ") || "–"],
        ["duration", `${approval.duration_s.toFixed(1)} s`],
        ["TRE", mm(approval.tre_mm)],
        ["approvers", approval.approvers.join(", ")],
      ]),
      el("p", { "data-testid": "approval-expiry", id: "approval-expiry" }),
      mayApprove ? "" : el("p", { class: "note" }, `this viewer acts as ${identity.join(" / ") || "?"}: not an approver`),
    );
    this.pending = { approval, may_approve: mayApprove };
    // One approval per click, and no second while the first is on its way (a double click).
    approve.onclick = () => {
      if (approve.disabled || this.approving !== null) return;
      const key = approvalKey(approval);
      this.approving = key;
      this.tick();
      void this.actions.approve(approval.plan_id, approval.digest).then((answer) => {
        // Accepted, the request is used up and the server's next approval state ends it; refused
        // or lost, the button comes back (the reply line says why).
        const accepted = answer.type === "reply" && answer.accepted;
        if (!accepted && this.approving === key) this.approving = null;
        this.tick();
      });
    };
    this.tick();
  }

  // The approval's countdown against the server's clock, and the approve button; called often.
  tick(): void {
    const approve = byId<HTMLButtonElement>("approve");
    const expiry = document.getElementById("approval-expiry");
    if (!this.pending || !expiry) {
      approve.hidden = true;
      return;
    }
    const { approval, may_approve } = this.pending;
    const view = approvalView({
      expires_at_unix_s: approval.expires_at_unix_s,
      server_now_s: this.actions.serverNow_s(),
      connected: this.connected,
      may_approve,
      in_flight: this.approving === approvalKey(approval),
    });
    expiry.textContent = view.expiry_text;
    expiry.className = view.urgent ? "warning" : "";
    expiry.dataset.expired = String(view.expired);
    approve.hidden = view.approve_hidden;
    approve.disabled = view.approve_disabled;
    approve.textContent = view.approve_label;
  }

  // The confirmation CT's measurement: where it stands, the summary (mean ± SD, max, min, RMS),
  // the targets without a seed and the extra seeds, and the tissues fitted from the errors.
  verification(verification: VerificationState | undefined): void {
    if (!this.shown.changed("verification", verification)) return;
    const body = byId("verification-body");
    if (!verification || verification.status === "none" || verification.status === "") {
      body.replaceChildren(
        el("p", { class: "small", "data-testid": "verification-status" },
          "no confirmation CT measured: load one after motion (Workflow)"),
        verification?.message ? el("p", { class: "bad", "data-testid": "verification-message" }, verification.message) : "",
      );
      return;
    }
    const v = verification;
    const measuring = v.status === "measuring";
    const ids = (prefix: string, list: number[]) => (list.length ? list.map((id) => `${prefix}${id}`).join(", ") : "none");
    const rows: [string, string, string?, string?][] = [
      ["status", measuring ? `measuring ${v.measuring_source}` : v.status, "verification-status"],
      ["confirmation CT", v.source || "–", "verification-source"],
    ];
    if (v.message) rows.push(["message", v.message, "verification-message"]);
    if (v.source) {
      rows.push(
        ["registration", registrationText(v), "verification-registration"],
        ["seeds found", v.detection_summary || "–", "verification-detection"],
        ["error", meanSd(v.error), "verification-error", "|error|: mean ± sample SD"],
        ["", extremes(v.error), "verification-error-extremes"],
        ["lateral", `${meanSd(v.lateral)} · ${extremes(v.lateral)}`, "verification-lateral", "across the insertion axis"],
        ["depth", `${meanSd(v.depth, true)} · ${extremes(v.depth, true)}`, "verification-depth", "+ deeper than planned; the mean is the depth bias"],
        ["missing targets", ids("T", v.missing_targets), "verification-missing", "reached, without a seed"],
        ["extra seeds", ids("S", v.extra_seeds), "verification-extra", "matched to no target"],
      );
    }
    rows.push(["aim tissue", v.aim_tissue || "none (nominal joints)", "verification-aim-tissue"]);
    const parts: (Node | string)[] = [];
    if (v.summary) parts.push(el("pre", { "data-testid": "verification-summary" }, v.summary));
    parts.push(facts(rows));
    if (v.fitted_tissues.length > 0) {
      const head = el("tr", {}, ...["tissue", "λ1 ± SE", "λ2 ± SE", "RMS (mm)", "bicycle", "none", "targets", ""].map((h) => el("th", {}, h)));
      const body = v.fitted_tissues.map((t) =>
        el(
          "tr",
          { "data-testid": `fitted-tissue-${t.name}`, title: t.yaml },
          el("td", {}, t.name),
          el("td", {}, withSe(t.lambda1, t.lambda1_se)),
          el("td", {}, withSe(t.lambda2, t.lambda2_se)),
          el("td", {}, fixed(t.rms_mm, 3)),
          el("td", {}, fixed(t.rms_bicycle_mm, 3)),
          el("td", {}, fixed(t.rms_no_deflection_mm, 3)),
          el("td", {}, String(t.targets)),
          el("td", { class: "warning" }, t.limit),
        ),
      );
      parts.push(
        el("p", { class: "small" }, "tissues fitted from the errors (RMS of measured − predicted landing: this model, the plain bicycle model, no deflection):"),
        el("table", { class: "fitted", "data-testid": "fitted-tissues" }, el("thead", {}, head), el("tbody", {}, ...body)),
      );
    }
    body.replaceChildren(...parts);
  }

  motion(motion: MotionState | undefined): void {
    if (!this.shown.changed("motion", motion && { ...motion, uptime_s: 0 })) return;
    const body = byId("motion-body");
    if (!motion) {
      body.replaceChildren("no motion state yet");
      return;
    }
    const [theta_c_rad, z_c_mm, z_s_mm] = motion.joints;
    body.replaceChildren(
      facts([
        ["controller", motion.controller],
        ["state", motion.state, "motion-state"],
        ["link", motion.lifecycle, "motion-lifecycle"],
        ["move", motion.move_count > 0 ? `${motion.move_index} / ${motion.move_count} ${motion.move_kind}` : "–"],
        ["plan", motion.plan_id ? `${motion.plan_id} → T${motion.target_id}` : "–"],
        ["joints", `θc ${(theta_c_rad * kDegPerRad).toFixed(1)}°, zc ${mm(z_c_mm)}, zs ${mm(z_s_mm)}`],
        ["steps", motion.steps.join(", ")],
        ["tip (LPS)", motion.tip_lps ? `${formatLps(motion.tip_lps)} mm` : "–"],
        ["fault", motion.fault || "–", "motion-fault"],
      ]),
    );
  }

  // The answer to what this viewer just asked, at once: "accepted" or the server's reason.
  reply(what: string, answer: Answer): void {
    // A command that starts background work (load_volume, auto_fiducials, load_confirmation) is
    // accepted when the work starts; its job's outcome follows on the job line (jobOutcome).
    if (answer.type === "reply" && answer.accepted && answer.job > 0) {
      this.showJob(jobStartedText(what, answer.job), "", answer.job);
    }
    const text = replyText(what, answer);
    const ok = answer.type === "reply" && answer.accepted;
    const line = byId("last-reply");
    line.textContent = text;
    line.title = text;
    line.className = ok ? "ok" : "bad";
    line.dataset.count = String(++this.replies);
  }

  // A background job ended. Every page hears every outcome; this page shows the one its own last
  // command started (other pages' work shows in the state panels as it always did).
  jobOutcome(outcome: JobOutcomeMessage): void {
    const line = byId("last-job");
    if (line.dataset.job !== String(outcome.job)) return;
    this.showJob(jobOutcomeText(outcome), outcome.status === "done" ? "ok" : "bad");
  }

  private showJob(text: string, className: string, job?: number): void {
    const line = byId("last-job");
    line.hidden = false;
    line.textContent = text;
    line.title = text;
    line.className = className;
    if (job !== undefined) line.dataset.job = String(job);
  }
}
