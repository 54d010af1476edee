// The real services the end-to-end tests start in a temporary directory on loopback:
// voxeld with its HTTP port, and HAProxy terminating TLS in front of it exactly as the
// README's docs/haproxy.cfg deploys it (a self-signed certificate made with openssl, free
// ports, no daemon, chroot or user). Every wait has a deadline; stop() kills whatever was
// started and removes the directory, and so does the process's exit.
import { execFileSync, spawn } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { request } from "node:https";
import { createServer } from "node:net";
import { tmpdir } from "node:os";
import { join } from "node:path";

export const haproxy = ["/usr/sbin/haproxy", "/usr/bin/haproxy"].find((p) => existsSync(p)) ?? null;
export const openssl = ["/usr/bin/openssl"].find((p) => existsSync(p)) ?? null;

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/** A free loopback port (closed again before it is returned). */
export function freePort() {
  return new Promise((resolve, reject) => {
    const s = createServer();
    s.once("error", reject);
    s.listen(0, "127.0.0.1", () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
  });
}

export class Services {
  /** @param {string} prefix the temporary directory's name prefix */
  constructor(prefix) {
    this.dir = mkdtempSync(join(tmpdir(), prefix));
    this.children = [];
    this.logs = "";
    process.on("exit", () => this.children.forEach((c) => c.kill("SIGKILL")));
  }

  start(cmd, args) {
    const child = spawn(cmd, args, { cwd: this.dir, stdio: ["ignore", "pipe", "pipe"] });
    child.stdout.on("data", (d) => { this.logs += d; });
    child.stderr.on("data", (d) => { this.logs += d; });
    child.on("error", (e) => { this.logs += `${cmd}: ${e.message}\n`; });
    this.children.push(child);
    return child;
  }

  async readPort(file, child, what) {
    const deadline = Date.now() + 20000;
    for (;;) {
      if (child.exitCode !== null) throw new Error(`${what} exited ${child.exitCode}: ${this.logs}`);
      if (Date.now() > deadline) throw new Error(`${what} wrote no port in 20 s: ${this.logs}`);
      try {
        const port = Number(readFileSync(join(this.dir, file), "utf8").trim());
        if (port) return port;
      } catch {}
      await sleep(50);
    }
  }

  /** voxeld in memory with its HTTP port serving `root` (and `extra` flags); resolves to that port. */
  async voxeld(path, root, extra = []) {
    const server = this.start(path, ["--in-memory", "--seed", "1", "--threads", "2", "--port", "0", "--port-file", "port",
      "--http-port", "auto", "--http-port-file", "http_port", "--http-root", root, "--log-level", "warn", ...extra]);
    return this.readPort("http_port", server, "voxeld");
  }

  /** HAProxy on a free port passing TLS to `httpPort`, as docs/haproxy.cfg; resolves to its port. */
  async tlsProxy(httpPort) {
    const dir = this.dir;
    execFileSync(openssl, ["req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
      "-keyout", join(dir, "key.pem"), "-out", join(dir, "cert.pem")], { stdio: "ignore", timeout: 30000 });
    writeFileSync(join(dir, "site.pem"), readFileSync(join(dir, "cert.pem")) + readFileSync(join(dir, "key.pem")));
    const tlsPort = await freePort();
    const config = readFileSync(new URL("../../../docs/haproxy.cfg", import.meta.url), "utf8")
      .replace("/etc/haproxy/voxeld.pem", join(dir, "site.pem"))
      .replace("0.0.0.0:443", `127.0.0.1:${tlsPort}`)
      .replace("127.0.0.1:7780", `127.0.0.1:${httpPort}`)
      .replace(/^\s*(log|chroot|user|group|daemon|stats socket).*$/gm, "");
    writeFileSync(join(dir, "haproxy.cfg"), config);
    const proxy = this.start(haproxy, ["-db", "-f", join(dir, "haproxy.cfg")]);
    const deadline = Date.now() + 20000;
    while (Date.now() < deadline) {
      if (proxy.exitCode !== null) throw new Error(`haproxy exited ${proxy.exitCode}: ${this.logs}`);
      if ((await httpsStatus(tlsPort, "/")) === 200) return tlsPort;
      await sleep(100);
    }
    throw new Error(`haproxy did not serve the page on ${tlsPort}: ${this.logs}`);
  }

  async stop() {
    for (const c of this.children) {
      if (c.exitCode === null && c.signalCode === null) {
        c.kill("SIGKILL");
        await new Promise((r) => c.once("exit", r));
      }
    }
    rmSync(this.dir, { recursive: true, force: true });
  }
}

/** GET over TLS (any certificate): the status, 0 when it fails. */
export function httpsStatus(port, path) {
  return new Promise((resolve) => {
    const req = request({ host: "127.0.0.1", port, path, rejectUnauthorized: false, timeout: 3000 }, (res) => {
      res.resume();
      resolve(res.statusCode);
    });
    req.on("timeout", () => req.destroy(new Error("timeout")));
    req.on("error", () => resolve(0));
    req.end();
  });
}
