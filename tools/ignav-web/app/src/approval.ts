// What the approval panel shows of a pending request besides its summary: the countdown and
// the approve button. Pure, so the rule reads in one place: an expired request cannot be
// approved, nothing can be approved from a page that cannot reach the server, and an approval
// on its way is not sent twice.

export interface ApprovalInputs {
  expires_at_unix_s: number; // the server's clock
  server_now_s: number | null; // the page's estimate of the server's clock (clock.ts)
  connected: boolean; // the page reaches the server
  may_approve: boolean; // this page's identity is an approver
  in_flight: boolean; // this page's approval of this request awaits its answer
}

export interface ApprovalView {
  expiry_text: string;
  expired: boolean;
  urgent: boolean; // little or no time left: shown as a warning
  approve_hidden: boolean;
  approve_disabled: boolean;
  approve_label: string;
}

const kUrgentS = 10;

export function approvalView(i: ApprovalInputs): ApprovalView {
  const left_s = i.server_now_s === null ? null : i.expires_at_unix_s - i.server_now_s;
  const expired = left_s !== null && left_s <= 0;
  let expiry_text: string;
  if (expired) expiry_text = "expired: request approval again";
  else if (left_s === null) expiry_text = "expiry unknown (no time from the server yet)";
  else expiry_text = `expires in ${Math.ceil(left_s)} s`;
  if (!i.connected && !expired) expiry_text = "cannot approve: the server is not reachable from this page";
  return {
    expiry_text,
    expired,
    urgent: !i.connected || left_s === null || left_s <= kUrgentS,
    approve_hidden: !i.may_approve || expired,
    approve_disabled: !i.connected || i.in_flight || expired || left_s === null,
    approve_label: i.in_flight ? "Approving…" : "Approve this motion",
  };
}
