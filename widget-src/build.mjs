// Builds the editor's front end into controlkit/widget/static/ (editor.js, editor.css).
//   cd widget-src && npm ci && npm run build
// The output is committed, so installing controlkit needs no node.
import { build } from "esbuild";
import { statSync } from "node:fs";

const outdir = new URL("../controlkit/widget/static/", import.meta.url).pathname;
await build({
  entryPoints: { editor: "src/editor.jsx" },
  bundle: true,
  format: "esm",
  minify: true,
  target: ["es2020"],
  outdir,
  jsx: "automatic",
  define: { "process.env.NODE_ENV": '"production"' },
  legalComments: "eof",
  logLevel: "info",
});
for (const name of ["editor.js", "editor.css"]) {
  console.log(`${name}: ${(statSync(outdir + name).size / 1024).toFixed(1)} KiB`);
}
