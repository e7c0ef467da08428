// The station against MOSER, in Debian's chromium driven headless by playwright-core.
//
//   node tests/browser/moser.mjs URL TOKEN SCREENSHOT_DIR
//
// URL is the station's page; TOKEN the one it was started with. Checks, in order: the page
// lists the 7 modules running; the robot's marker moves on the map; the intruder alert
// appears; clicking deactivate on near_ir changes its state (and activate brings it back);
// clicking upgrade on near_ir replaces its process live (the row's pid and upgrade count);
// a page with a wrong token is read-only and its commands are refused; a malformed message
// closes that connection with a reason; "stop system" asks first and stops the system only
// when confirmed. Writes a screenshot of each view. Exits 1 with the
// reason on the first check that fails.
import { launch, fail, step, screenshot } from "./station-lib.mjs";

const [url, token, shots] = process.argv.slice(2);
// Whatever hangs, the test ends and says so.
setTimeout(() => { console.error("moser.mjs: not done within 10 minutes"); process.exit(1); }, 600_000).unref();
// What the page had when a check failed: the robot's pose, the plan's state, the map, the
// station's problems and the page's own drawing errors.
async function seen(page) {
  return page.evaluate(() => {
    const v = window.station, s = v.state || { blackboards: {}, problems: [] };
    return JSON.stringify({
      pose: v.pose, map: v.map !== null, mapError: v.mapError, errors: v.errors,
      mobility: s.blackboards.mobility, high_level: s.blackboards.high_level,
      problems: s.problems, t_ms: s.t_ms, state_age_ms: v.stateAt ? Date.now() - v.stateAt : null, events: (s.events || []).slice(-8),
    });
  });
}
const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1500, height: 1300 } });
  await page.goto(`${url}?token=${token}`);

  await step("the page lists the 7 modules running, with their heartbeats' age", () =>
    page.waitForFunction(() =>
      document.querySelectorAll('#modules tbody tr[data-state="running"]').length === 7 &&
      [...document.querySelectorAll('#modules tbody tr')].every((tr) => tr.children[7].textContent.endsWith(" ago")) &&
      document.querySelector("#module-count").textContent.includes("1 page watching") &&
      document.body.dataset.mode === "commanding", null, { timeout: 60_000 }));

  await step("the robot's marker moves on the map", async () => {
    try {
      await page.waitForFunction(() => window.station.pose !== null, null, { timeout: 60_000 });
      const first = await page.evaluate(() => ({ ...window.station.pose }));
      await page.waitForFunction((p) => {
        const q = window.station.pose;
        return Math.hypot(q.x - p.x, q.y - p.y) > 0.5;
      }, first, { timeout: 120_000 });
    } catch (e) {
      fail(`${e.message || e}; the page saw ${await seen(page)}`);
    }
    const shown = await page.locator("#robot-pose").getAttribute("data-x");
    if (shown === null) fail("the map shows no robot position");
  });
  await screenshot(page, "#map-view", `${shots}/station-moser-map.png`);

  await step("the intruder alert appears", () =>
    page.locator("#events li.alert").first().waitFor({ timeout: 180_000 }));

  await step("deactivate on near_ir changes its state", async () => {
    const row = page.locator('#modules tr[data-module="near_ir"]');
    await row.locator('button[data-action="toggle"]').click();
    await page.waitForFunction(() =>
      document.querySelector('#modules tr[data-module="near_ir"]').dataset.active === "false",
      null, { timeout: 30_000 });
    await page.locator("#answers li.ok").first().waitFor({ timeout: 10_000 });
    await page.locator("#events li", { hasText: "near_ir deactivated" }).first().waitFor({ timeout: 10_000 });
    await row.locator('button[data-action="toggle"]').click();
    await page.waitForFunction(() =>
      document.querySelector('#modules tr[data-module="near_ir"]').dataset.active === "true",
      null, { timeout: 30_000 });
  });

  await step("upgrade on near_ir: a new process takes it over, the row shows its pid and count", async () => {
    const row = page.locator('#modules tr[data-module="near_ir"]');
    const pid = await row.locator("td").nth(4).textContent();
    await row.locator('button[data-action="upgrade"]').click();
    await page.waitForFunction((pid) => {
      const cells = document.querySelector('#modules tr[data-module="near_ir"]').children;
      return cells[6].textContent === "1" && cells[4].textContent !== pid && cells[2].textContent === "running";
    }, pid, { timeout: 60_000 });
  });
  await screenshot(page, null, `${shots}/station-moser.png`);

  await step("a wrong token cannot command", async () => {
    const other = await browser.newPage();
    await other.goto(`${url}?token=wrong-${token}`);
    await other.waitForFunction(() => document.body.dataset.mode === "read-only", null, { timeout: 30_000 });
    await other.waitForFunction(() =>
      document.querySelectorAll('#modules tbody tr[data-state="running"]').length === 7, null, { timeout: 30_000 });
    const disabled = await other.locator('#modules tr[data-module="near_ir"] button[data-action="toggle"]').isDisabled();
    if (!disabled) fail("a read-only page offers deactivate");
    const upgrade = await other.locator('#modules tr[data-module="near_ir"] button[data-action="upgrade"]').isDisabled();
    if (!upgrade) fail("a read-only page offers upgrade");
    // Sent anyway, the command is refused.
    const m = await other.evaluate(() => new Promise((resolve, reject) => {
      const ws = window.station.ws;
      ws.addEventListener("message", (e) => {
        const m = JSON.parse(e.data);
        if (m.type === "answer" && m.id === 99) resolve(m);
      });
      ws.send(JSON.stringify({ op: "call", id: 99, module: "near_ir", method: "deactivate", args: [] }));
      setTimeout(() => reject(new Error("no answer within 30 s")), 30_000);
    }));
    if (m.ok || !m.text.includes("read-only")) fail(`a wrong token's command was answered ${JSON.stringify(m)}`);
    const active = await page.evaluate(() =>
      document.querySelector('#modules tr[data-module="near_ir"]').dataset.active);
    if (active !== "true") fail(`near_ir's state changed through a wrong token: active=${active}`);
    await other.close();
  });

  await step("a malformed message closes its connection with a reason", async () => {
    const closed = await page.evaluate(() => new Promise((resolve, reject) => {
      const ws = new WebSocket(`ws://${location.host}/ws`);
      ws.onopen = () => ws.send("not json at all");
      ws.onclose = (e) => resolve({ code: e.code, reason: e.reason });
      setTimeout(() => reject(new Error("not closed within 30 s")), 30_000);
    }));
    if (closed.code !== 1008 || !closed.reason.includes("malformed message")) {
      fail(`closed with ${JSON.stringify(closed)}`);
    }
  });
  await step("stopping the system asks first, and stops it only when confirmed", async () => {
    page.once("dialog", (d) => d.dismiss());
    await page.click("#system-stop");
    await page.waitForTimeout(1500);
    const running = await page.evaluate(() =>
      document.querySelectorAll('#modules tbody tr[data-state="running"]').length);
    if (running !== 7) fail(`a dismissed stop stopped modules: ${running} running`);
    page.once("dialog", (d) => d.accept());
    await page.click("#system-stop");
    await page.locator("#answers li.ok", { hasText: "supervisor.down" }).first().waitFor({ timeout: 30_000 });
    await page.waitForFunction(() =>
      document.querySelectorAll('#modules tbody tr[data-state="running"]').length < 7,
      null, { timeout: 60_000 });
  });
  console.log("moser: every check passed");
} catch (e) {
  console.error(e.message || e);
  process.exitCode = 1;
} finally {
  await browser.close();
}
