// The server's wall clock as this page can know it. The server stamps what it publishes with its
// own clock (Health.server_time_unix_s once a second; an approval request's publication time is
// expires_at_unix_s - expires_in_s), and a sample cannot arrive before it was written, so every
// sample says: offset = server - local >= server_time - local time of receipt. The largest of
// these lower bounds over a recent window is the estimate (the freshest, least delayed sample
// wins); the window lets the estimate follow a drift between the two clocks. The local clock is
// the page's monotonic one (performance.now()), so a wrong or stepped clock on the browser's
// machine changes nothing. Pure: the caller passes every time in.

export const kOffsetWindowS = 30;

interface OffsetSample {
  local_s: number; // when it was received, on the local clock
  offset_s: number; // server time - local_s: a lower bound on the true offset
}

export class ServerClock {
  private samples: OffsetSample[] = [];

  constructor(private readonly window_s = kOffsetWindowS) {}

  // A sample written at server_s (Unix seconds, the server's clock) and received at local_s.
  observe(server_s: number, local_s: number): void {
    if (!Number.isFinite(server_s) || server_s <= 0 || !Number.isFinite(local_s)) return;
    this.samples.push({ local_s, offset_s: server_s - local_s });
    // The newest sample always stays, however old: an estimate from it beats none.
    const newest = Math.max(...this.samples.map((s) => s.local_s));
    this.samples = this.samples.filter((s) => s.local_s >= newest - this.window_s);
  }

  // The server's clock now (Unix seconds), or null before the first sample.
  now_s(local_s: number): number | null {
    if (this.samples.length === 0) return null;
    return local_s + Math.max(...this.samples.map((s) => s.offset_s));
  }
}

// When the server published an approval request, on its own clock: the request carries its
// absolute expiry and the time left at publication. NaN when it does not say.
export function approvalPublishedAt_s(expires_at_unix_s: number, expires_in_s: number): number {
  return expires_at_unix_s > 0 ? expires_at_unix_s - expires_in_s : Number.NaN;
}
