// The WebSocket to the gateway (docs/WEB.md): numbers each request, hands its answer to the
// promise that sent it, forwards hello/state/connection messages, and reconnects after a loss
// with a short pause (0.1 s, then 0.2 s, then every 0.25 s) so that a restarted gateway is found
// again within about a quarter of a second. A refused connection costs next to nothing; one to an
// unreachable host takes the browser's own connect timeout before it fails, which paces the
// attempts by itself.
import type { Answer, GatewayMessage, HelloMessage, JobOutcomeMessage, Request, ServerState } from "./state";

const kFirstRetryMs = 100;
const kLongestRetryMs = 250;

export type SocketStatus =
  | { open: true }
  | { open: false; retry_in_ms: number }; // 0 while the first attempt is under way

export interface SocketEvents {
  hello(hello: HelloMessage): void; // every (re)connection begins with one
  state(topics: ServerState): void; // the named topics, each whole
  serverConnection(connected: boolean): void;
  status(status: SocketStatus): void;
  jobOutcome(outcome: JobOutcomeMessage): void;
}

export class GatewaySocket {
  private ws: WebSocket | null = null;
  private nextSeq = 1;
  private retryMs = kFirstRetryMs;
  private readonly pending = new Map<number, (answer: Answer) => void>();

  constructor(
    private readonly url: string,
    private readonly events: SocketEvents,
  ) {}

  start(): void {
    this.events.status({ open: false, retry_in_ms: 0 });
    this.connect();
  }

  // Resolves with the gateway's answer; a request that cannot be sent, or whose connection is
  // lost before the answer, resolves with an error "disconnected" (it may or may not have been
  // executed: the state that follows says).
  request(request: Request): Promise<Answer> {
    const ws = this.ws;
    if (!ws || ws.readyState !== WebSocket.OPEN) {
      return Promise.resolve(disconnected(-1, "not connected to the gateway"));
    }
    const seq = this.nextSeq++;
    return new Promise((resolve) => {
      this.pending.set(seq, resolve);
      ws.send(JSON.stringify({ ...request, seq }));
    });
  }

  // For tests and for a person who wants to see the viewer recover: drop the connection as a
  // network failure would.
  drop(): void {
    this.ws?.close();
  }

  private connect(): void {
    const ws = new WebSocket(this.url);
    this.ws = ws;
    ws.onmessage = (event) => this.receive(event.data);
    ws.onclose = () => {
      if (this.ws !== ws) return;
      this.ws = null;
      for (const [seq, resolve] of this.pending) resolve(disconnected(seq, "the connection to the gateway was lost"));
      this.pending.clear();
      const wait = this.retryMs;
      this.retryMs = Math.min(2 * this.retryMs, kLongestRetryMs);
      this.events.status({ open: false, retry_in_ms: wait });
      setTimeout(() => this.connect(), wait);
    };
    // An error is always followed by close, which does the work.
    ws.onerror = () => {};
  }

  private receive(data: unknown): void {
    if (typeof data !== "string") return;
    let message: GatewayMessage;
    try {
      message = JSON.parse(data) as GatewayMessage;
    } catch {
      console.warn("ignav-web: a message that is not JSON", data.slice(0, 200));
      return;
    }
    switch (message.type) {
      case "hello":
        this.retryMs = kFirstRetryMs;
        this.events.status({ open: true });
        this.events.hello(message);
        return;
      case "state":
        this.events.state(message.state);
        return;
      case "connection":
        this.events.serverConnection(message.server);
        return;
      case "job_outcome":
        this.events.jobOutcome(message);
        return;
      case "reply":
      case "slice":
      case "scene":
      case "error": {
        const resolve = this.pending.get(message.seq);
        if (!resolve) {
          console.warn("ignav-web: an answer to no request", message);
          return;
        }
        this.pending.delete(message.seq);
        resolve(message);
        return;
      }
    }
  }
}

function disconnected(seq: number, message: string): Answer {
  return { type: "error", seq, code: "disconnected", message };
}
