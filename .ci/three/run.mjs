// Serves the three.js check page and voltrack's outputs on 127.0.0.1 and
// opens it in headless Chromium (WebGL through SwiftShader), once per GLB.
// usage: node .ci/three/run.mjs OUTDIR TOL:GLB:OBJDIR [...]
//   GLB and OBJDIR are relative to OUTDIR; TOL is the largest vertex error
//   accepted, as a fraction of the bounding-box diagonal.
import { createServer } from "node:http";
import { readFile, mkdtemp } from "node:fs/promises";
import { execFile } from "node:child_process";
import { tmpdir } from "node:os";
import path from "node:path";

const ci = path.resolve(path.dirname(new URL(import.meta.url).pathname), "..");
const [outDir, ...cases] = process.argv.slice(2);
const roots = { "/node_modules/": path.join(ci, "node_modules"), "/three/": path.join(ci, "three"), "/out/": path.resolve(outDir) };
const types = { ".html": "text/html", ".js": "text/javascript", ".glb": "model/gltf-binary", ".gltf": "model/gltf+json", ".obj": "text/plain" };

const server = createServer(async (req, res) => {
  const url = decodeURIComponent(new URL(req.url, "http://x").pathname);
  const prefix = Object.keys(roots).find((p) => url.startsWith(p));
  const file = prefix && path.join(roots[prefix], url.slice(prefix.length));
  if (!file || !file.startsWith(roots[prefix])) return res.writeHead(404).end();
  try {
    const body = await readFile(file);
    res.writeHead(200, { "content-type": types[path.extname(file)] ?? "application/octet-stream" }).end(body);
  } catch {
    res.writeHead(404).end();
  }
});
await new Promise((ok) => server.listen(0, "127.0.0.1", ok));
const port = server.address().port;

const chromium = ["chromium", "chromium-browser"].find(() => true);
function open(url, profile) {
  const args = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu-sandbox",
    "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-quic",
    `--user-data-dir=${profile}`, "--virtual-time-budget=120000", "--dump-dom", url];
  return new Promise((ok, fail) => execFile(chromium, args, { maxBuffer: 1 << 24, timeout: 300000 }, (e, out, err) => (e ? fail(new Error(`${e.message}\n${err}`)) : ok(out))));
}

let failed = 0;
for (const c of cases) {
  const [tol, glb, objs] = c.split(":");
  const profile = await mkdtemp(path.join(tmpdir(), "voltrack-chromium-"));
  const url = `http://127.0.0.1:${port}/three/check.html?glb=/out/${glb}&objs=/out/${objs}&tol=${tol}`;
  const dom = await open(url, profile);
  const m = dom.match(/<pre id="result">([\s\S]*?)<\/pre>/);
  const text = m ? m[1].replace(/&quot;/g, '"').replace(/&lt;/g, "<").replace(/&gt;/g, ">").replace(/&amp;/g, "&") : "no result";
  let r;
  try { r = JSON.parse(text); } catch { r = { ok: false, error: `page said: ${text.slice(0, 300)}` }; }
  console.log(`${r.ok ? "PASS" : "FAIL"} ${glb}: ${JSON.stringify(r)}`);
  if (!r.ok) failed++;
}
server.close();
if (failed) {
  console.error(`three.js check: ${failed} of ${cases.length} failed`);
  process.exit(1);
}
console.log(`three.js check: ${cases.length} file(s) played in three.js ${JSON.parse(await readFile(path.join(ci, "node_modules/three/package.json"))).version}`);
