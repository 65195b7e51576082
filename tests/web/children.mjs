// The processes a browser test or bench starts (ignav-server, ignav-web): each is started with its
// output collected and resolves once its ready line appears; every one still running is killed
// when this node process exits, however it exits.
import { spawn } from "node:child_process";
import fs from "node:fs";
import path from "node:path";

export const kReadyTimeoutMs = 15000;

const running = ({ child }) => child.exitCode === null && child.signalCode === null;

export const children = [];
process.on("exit", () => {
  for (const record of children) if (running(record)) record.child.kill("SIGKILL");
});
for (const signal of ["SIGINT", "SIGTERM"]) process.on(signal, () => process.exit(1));

// Resolves with { name, child, output, match } once `readyPattern` matches its stdout.
export function startProcess(name, exe, argv, readyPattern, timeoutMs = kReadyTimeoutMs) {
  if (!fs.existsSync(exe)) throw new Error(`${exe} is missing: build the project first`);
  const child = spawn(exe, argv, { stdio: ["ignore", "pipe", "pipe"] });
  const record = { name, child, output: "", match: null };
  children.push(record);
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`${name} not ready in ${timeoutMs} ms`)), timeoutMs);
    child.stdout.on("data", (chunk) => {
      record.output += chunk.toString();
      const match = record.output.match(readyPattern);
      if (match && !record.match) {
        clearTimeout(timer);
        record.match = match;
        resolve(record);
      }
    });
    child.stderr.on("data", (chunk) => (record.output += chunk.toString()));
    child.on("exit", (code, signal) => {
      clearTimeout(timer);
      reject(new Error(`${name} exited (${code ?? signal}) before it was ready:\n${record.output.slice(-3000)}`));
    });
  });
}

// SIGKILL by default, as a crash would: nothing of the process's own shutdown runs.
export function kill(record, signal = "SIGKILL") {
  if (!running(record)) return Promise.resolve();
  return new Promise((resolve) => {
    record.child.once("exit", resolve);
    record.child.kill(signal);
  });
}

// SIGTERM to every one still running, SIGKILL after 3 s.
export async function stopChildren() {
  await Promise.all(
    children.filter(running).map((record) => {
      const force = setTimeout(() => record.child.kill("SIGKILL"), 3000);
      return kill(record, "SIGTERM").then(() => clearTimeout(force));
    }),
  );
}

// ignav-server on loopback DDS, with no OpenIGTLink listener, its session in `sessionDir`.
export function startServer({ build, config, domain, sessionDir, dds }) {
  return startProcess(
    "ignav-server",
    path.join(build, "server/ignav-server"),
    ["--config", config, "--domain", String(domain), "--session-dir", sessionDir, "--dds-config", dds, "--no-igtl"],
    /ignav-server ready/,
  );
}

// ignav-web as the client "operator" on `port` (0: any free one); its record's match[1] is the URL.
// `appDir`: the bundled app to serve (undefined: the build's own).
export function startGateway({ build, domain, dds, port, appDir }) {
  return startProcess(
    "ignav-web",
    path.join(build, "tools/ignav-web/ignav-web"),
    ["--dds-config", dds, "--domain", String(domain), "--port", String(port), "--client-id", "operator",
     ...(appDir ? ["--app-dir", appDir] : [])],
    /ignav-web ready url=(\S+)/,
  );
}
