// What the page says, in a banner that cannot be missed, when it is in no position to act: the
// server out of reach (then nothing on the page reaches the robot, not even its emergency stop),
// or the robot halted by an emergency stop or a fault. Pure, so the rule reads in one place.
import type { SocketStatus } from "./socket";

export interface ConnectionView {
  connected: boolean; // commands from this page reach the server
  header: string; // the short line in the header
  banner: string | null; // null: no banner
}

const kNoEstop =
  "Nothing on this page reaches the robot, not even its EMERGENCY STOP: use the robot's hardware " +
  "emergency stop or another station. What the page shows is the last state it received.";

// `server`: what the gateway last said of the server (null: it has not said yet).
export function connectionView(status: SocketStatus, server: boolean | null): ConnectionView {
  const gateway = status.open
    ? "gateway: connected"
    : status.retry_in_ms > 0
      ? `gateway: disconnected, retrying in ${(status.retry_in_ms / 1000).toFixed(1)} s`
      : "gateway: connecting…";
  const serverText = server === null ? "server: ?" : server ? "server: connected" : "server: not connected";
  const connected = status.open && server === true;
  let banner: string | null = null;
  if (!status.open) {
    banner = `NOT CONNECTED: this page cannot reach the ignav-web gateway (${gateway}). ${kNoEstop}`;
  } else if (server === false) {
    banner = `NOT CONNECTED: the gateway cannot reach ignav-server. ${kNoEstop}`;
  } else if (server === null) {
    banner = `NOT CONNECTED YET: waiting for the gateway to find ignav-server. ${kNoEstop}`;
  }
  return { connected, header: `${gateway} · ${serverText}`, banner };
}

// The banner for a halted robot, or null.
export function phaseBanner(phase: string, fault: string): string | null {
  if (phase === "emergency") {
    return (
      "EMERGENCY STOP: the robot was halted and nothing moves. Check the patient and the robot; " +
      "then an approver presses Reset emergency (the server checks the motor positions first), " +
      "or Home after homing the robot by hand."
    );
  }
  if (phase === "fault") {
    return (
      `ROBOT FAULT${fault ? `: ${fault}` : ""}. The robot was halted. Clear the cause; then an ` +
      "approver presses Reset emergency (the server checks the motor positions first)."
    );
  }
  return null;
}
