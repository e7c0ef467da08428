// What the station's browser tests share: Debian's chromium, started headless as this
// machine needs it (no sandbox as root, no background connections to a network it does not
// have), and steps that say which check failed.
import { chromium } from "playwright-core";

export const CHROMIUM = process.env.MODBOT_CHROMIUM || "/usr/bin/chromium";

export function launch() {
  return chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: [
      "--no-sandbox",
      "--disable-gpu",
      "--disable-quic",
      "--no-first-run",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
    ],
  });
}

export function fail(why) {
  throw new Error(why);
}

// Runs one check; a failure names it.
export async function step(name, f) {
  const started = Date.now();
  try {
    await f();
  } catch (e) {
    throw new Error(`${name}: ${e.message || e}`);
  }
  console.log(`ok: ${name} (${Date.now() - started} ms)`);
}

// A screenshot of `selector` (or the whole page).
export async function screenshot(page, selector, path) {
  if (selector) await page.locator(selector).screenshot({ path });
  else await page.screenshot({ path, fullPage: true });
  console.log(`screenshot: ${path}`);
}
