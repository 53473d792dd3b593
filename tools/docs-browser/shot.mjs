// Opens one page of the built documentation site in headless Chromium, as a reader's
// browser would, saves a screenshot and says what the page shows:
//
//   node tools/docs-browser/shot.mjs PAGE.html SHOT.png [--json]
//
// It prints the title, the headings, the visible link texts, each image with its natural
// size, and every console error, uncaught page error and failed request; with --json, the
// same as one JSON object (test/test_docs_browser.py reads it).  It exits 1 when the page
// has a console or page error, a failed request, an image that did not load (natural
// width 0) or a link into the site whose file does not exist; so `make docs-shot` fails
// on a page a reader would see broken.
//
// The browser is the Chromium that `npm ci` in this folder unpacked (extract.mjs): it
// comes from the npm registry alone, with no download of its own.
import { existsSync, statSync } from "node:fs";
import { resolve } from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";
import puppeteer from "puppeteer-core";
import { CHROMIUM } from "./extract.mjs";

// Chromium's flags for this machine, each for a reason:
//  --no-sandbox: developers' and CI's machines run as root, where Chromium's sandbox
//    refuses to start;
//  --no-zygote: the zygote is a sandbox helper, and refuses to start without a sandbox;
//  --disable-gpu: no GPU here; pages are drawn by the software rasterizer.
const ARGS = ["--no-sandbox", "--no-zygote", "--disable-gpu"];
// Wide enough for the theme's sidebar beside the text, as on a laptop.
const VIEWPORT = { width: 1280, height: 900 };
const TIMEOUT_MS = 60_000;

/** What the page shows, read in the page itself (runs inside the browser). */
function readPage() {
  const visible = (element) => element.checkVisibility();
  // A heading's own text, without Sphinx's "¶" permalink.
  const text = (element) => {
    const copy = element.cloneNode(true);
    copy.querySelectorAll(".headerlink").forEach((link) => link.remove());
    return copy.textContent.replace(/\s+/g, " ").trim();
  };
  // The page's own top heading: the first in its main text, not the sidebar's logo.
  const top = document.querySelector('[role="main"] h1') ?? document.querySelector("h1");
  return {
    title: document.title,
    topHeading: top ? text(top) : null,
    headings: [...document.querySelectorAll("h1, h2, h3")].filter(visible).map((h) => ({
      level: Number(h.tagName.slice(1)),
      text: text(h),
    })),
    links: [...document.querySelectorAll("a[href]")]
      .filter((a) => visible(a) && !a.classList.contains("headerlink"))
      .map((a) => ({ text: text(a), href: a.href })),
    images: [...document.images].map((img) => ({
      src: img.currentSrc || img.src,
      naturalWidth: img.naturalWidth,
      naturalHeight: img.naturalHeight,
    })),
  };
}

/** The file a link into the site names (its fragment and query dropped), or null for a link out. */
function linkedFile(href) {
  const url = new URL(href);
  return url.protocol === "file:" ? fileURLToPath(new URL(url.pathname, url)) : null;
}

async function main(argv) {
  const json = argv.includes("--json");
  const [page, shot] = argv.filter((arg) => arg !== "--json");
  if (!page || !shot) {
    console.error("usage: node shot.mjs PAGE.html SHOT.png [--json]");
    return 2;
  }
  if (!existsSync(CHROMIUM)) {
    console.error(`no headless Chromium at ${CHROMIUM}: run \`make browser\` (npm ci in tools/docs-browser)`);
    return 2;
  }
  const url = pathToFileURL(resolve(page)).href;
  const consoleErrors = [];
  const pageErrors = [];
  const failedRequests = [];
  const browser = await puppeteer.launch({
    executablePath: CHROMIUM, headless: "shell", args: ARGS, timeout: TIMEOUT_MS,
  });
  let shown;
  try {
    const tab = await browser.newPage();
    tab.on("console", (message) => {
      if (message.type() === "error") {
        consoleErrors.push(`${message.text()} (${message.location().url ?? ""})`);
      }
    });
    tab.on("pageerror", (error) => pageErrors.push(String(error)));
    tab.on("requestfailed", (request) => failedRequests.push(`${request.url()}: ${request.failure()?.errorText}`));
    await tab.setViewport(VIEWPORT);
    await tab.goto(url, { waitUntil: "load", timeout: TIMEOUT_MS });
    await tab.evaluate(() => document.fonts.ready);
    shown = await tab.evaluate(readPage);
    await tab.screenshot({ path: shot, fullPage: true });
  } finally {
    await browser.close();
  }
  const missingTargets = [...new Set(shown.links.map((link) => linkedFile(link.href)))]
    .filter((file) => file !== null && !existsSync(file));
  const brokenImages = shown.images.filter((image) => !(image.naturalWidth > 0 && image.naturalHeight > 0));
  const report = {
    page: url, screenshot: resolve(shot), screenshotBytes: statSync(shot).size, viewport: VIEWPORT,
    ...shown, consoleErrors, pageErrors, failedRequests, missingTargets, brokenImages,
  };
  if (json) {
    console.log(JSON.stringify(report, null, 1));
  } else {
    console.log(`page: ${report.page}`);
    console.log(`screenshot: ${report.screenshot} (${report.screenshotBytes} bytes, ${VIEWPORT.width} px wide, full page)`);
    console.log(`title: ${report.title}`);
    console.log(`top heading: ${report.topHeading}`);
    console.log("headings (sidebar's included):");
    for (const heading of report.headings) console.log(`  ${"  ".repeat(heading.level - 1)}h${heading.level} ${heading.text}`);
    const internal = report.links.filter((link) => linkedFile(link.href) !== null).length;
    console.log(`visible links: ${report.links.length} (${internal} into the site, ${report.links.length - internal} out)`);
    for (const link of report.links) console.log(`  ${link.text || "(no text)"} -> ${link.href}`);
    console.log(`images: ${report.images.length}`);
    for (const image of report.images) console.log(`  ${image.naturalWidth}x${image.naturalHeight} ${image.src}`);
    for (const [name, items] of [["console errors", consoleErrors], ["page errors", pageErrors],
      ["failed requests", failedRequests], ["links to missing files", missingTargets],
      ["broken images", brokenImages.map((image) => image.src)]]) {
      console.log(`${name}: ${items.length}`);
      for (const item of items) console.log(`  ${item}`);
    }
  }
  const broken = consoleErrors.length + pageErrors.length + failedRequests.length + missingTargets.length
    + brokenImages.length;
  return broken ? 1 : 0;
}

process.exitCode = await main(process.argv.slice(2));
