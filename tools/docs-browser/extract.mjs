// Unpacks the Chromium that @sparticuz/chromium ships brotli-compressed inside its npm
// tarball into node_modules/.chromium, next to its SwiftShader libraries.
//
// Why here and not at first use: the package unpacks into os.tmpdir() (/tmp/chromium),
// which every user and every checkout on a machine share, so two runs at once (two
// pytest workers, CI's two platforms) could run a half-written binary, and a stale one
// of another version would be taken as is.  Unpacking once, at `npm ci` (the package's
// postinstall), into this checkout's own node_modules removes both.
import { mkdirSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

export const CHROMIUM_DIR = join(dirname(fileURLToPath(import.meta.url)), "node_modules", ".chromium");
export const CHROMIUM = join(CHROMIUM_DIR, "chromium");

if (process.argv[1] === fileURLToPath(import.meta.url)) {
  mkdirSync(CHROMIUM_DIR, { recursive: true });
  // os.tmpdir() reads TMPDIR at each call: the package unpacks where we point it.
  process.env.TMPDIR = CHROMIUM_DIR;
  const { default: chromium } = await import("@sparticuz/chromium");
  const path = await chromium.executablePath();
  if (path !== CHROMIUM) {
    throw new Error(`@sparticuz/chromium unpacked to ${path}, expected ${CHROMIUM}`);
  }
  console.log(`headless Chromium: ${path}`);
}
