// npm run build:viewer -- [OUTDIR]: bundles the viewer (viewer/main.js, three.js and the
// client library) with esbuild into OUTDIR/viewer.js and copies viewer/index.html beside
// it. OUTDIR defaults to <repo>/build/web, where voxeld serves it from by default.
// Nothing is fetched at run time: the page loads only these two files.
import { copyFileSync, mkdirSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { build } from "esbuild";

const here = dirname(fileURLToPath(import.meta.url));
const web = join(here, "..");
const out = resolve(process.argv[2] ?? join(web, "..", "..", "build", "web"));

mkdirSync(out, { recursive: true });
const result = await build({
  entryPoints: [join(web, "viewer", "main.js")],
  outfile: join(out, "viewer.js"),
  bundle: true,
  format: "iife",
  platform: "browser",
  target: ["es2022"],
  minify: true,
  sourcemap: process.env.VIEWER_SOURCEMAP ? "linked" : false,
  legalComments: "linked",
  logLevel: "warning",
  metafile: true,
});
copyFileSync(join(web, "viewer", "index.html"), join(out, "index.html"));
const bytes = Object.values(result.metafile.outputs).reduce((n, o) => n + o.bytes, 0);
console.log(`viewer: ${out}/index.html + viewer.js (${(bytes / 1024).toFixed(0)} KiB)`);
