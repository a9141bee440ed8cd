// A headless Chromium driven by one JSON command a line on stdin, one JSON answer a line on stdout, for the Python
// browser tests (tests/viewer/browser.py) and the frame-rate measurement. Debian's chromium, playwright-core from
// npm (viewer/web/package.json); no browser is downloaded. Commands:
//   {"op": "open", "url", "width", "height"}           -> {"ok": true, "value": page index}
//   {"op": "eval", "page", "expr"}                     -> the expression's value (a promise is awaited)
//   {"op": "wait", "page", "expr", "timeout_ms"}       -> polls every 50 ms until the expression is truthy
//   {"op": "fill" | "click", "page", "selector", "value"}
//   {"op": "files", "page", "selector", "paths"}       -> sets a file input's files
//   {"op": "screenshot", "page", "path"}
//   {"op": "console", "page"}                          -> the page's console messages and errors so far
//   {"op": "quit"}
// A failed command answers {"ok": false, "error": "..."}.
import { mkdtempSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { createInterface } from "node:readline";
import { chromium } from "playwright-core";

const CHROMIUM = process.env.SS_CHROMIUM || "/usr/bin/chromium";
// This machine's network is closed: nothing may try to reach out (QUIC, component updates, sync, first-run pings).
const FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
  "--disable-background-networking", "--disable-component-update", "--disable-sync"];

const profile = mkdtempSync(join(tmpdir(), "ss-viewer-chromium-"));
let context = null;
const pages = [];
const logs = [];

async function run(cmd) {
  switch (cmd.op) {
    case "open": {
      if (!context)
        context = await chromium.launchPersistentContext(profile, {
          executablePath: CHROMIUM, headless: true, args: FLAGS,
          // The TLS tests serve the page with a certificate of a CA made for the test (loopback only).
          ignoreHTTPSErrors: true,
          viewport: { width: cmd.width || 1280, height: cmd.height || 800 },
        });
      const page = pages.length === 0 && context.pages().length ? context.pages()[0] : await context.newPage();
      const log = [];
      page.on("console", (m) => log.push(`${m.type()}: ${m.text()}`));
      page.on("pageerror", (e) => log.push(`pageerror: ${e.message}`));
      if (cmd.width) await page.setViewportSize({ width: cmd.width, height: cmd.height || 800 });
      await page.goto(cmd.url, { waitUntil: "load", timeout: 30000 });
      pages.push(page);
      logs.push(log);
      return pages.length - 1;
    }
    case "eval": return await pages[cmd.page].evaluate(cmd.expr);
    case "wait": {
      await pages[cmd.page].waitForFunction(cmd.expr, null, { timeout: cmd.timeout_ms || 30000, polling: 50 });
      return true;
    }
    case "fill": await pages[cmd.page].fill(cmd.selector, cmd.value); return true;
    case "click": await pages[cmd.page].click(cmd.selector); return true;
    case "files": await pages[cmd.page].setInputFiles(cmd.selector, cmd.paths); return true;
    case "screenshot": await pages[cmd.page].screenshot({ path: cmd.path }); return cmd.path;
    case "console": return logs[cmd.page];
    case "quit": return true;
    default: throw new Error(`unknown op '${cmd.op}'`);
  }
}

const lines = createInterface({ input: process.stdin });
for await (const line of lines) {
  if (!line.trim()) continue;
  let cmd;
  let answer;
  try {
    cmd = JSON.parse(line);
    answer = { ok: true, value: (await run(cmd)) ?? null };
  } catch (e) {
    answer = { ok: false, error: String(e && e.message ? e.message : e) };
  }
  process.stdout.write(JSON.stringify(answer) + "\n");
  if (cmd && cmd.op === "quit") break;
}
if (context) await context.close();
rmSync(profile, { recursive: true, force: true });
