#!/usr/bin/env python3
"""The operator's dashboard in a real browser: Debian's headless Chromium driven by Selenium
against a rangexd fed by a simulated 4-lane plant.

Checks: the page loads without console errors and shows one tile per lane; every reject
appears in the live feed after its decision (the lag is printed; its bound, 60 s, is for a feed
that stalls, not for speed: a busy CI machine showed 2.8 s); clicking it shows its four images with its
fragments boxed; the records search returns the stored fillets (read from the store's SQLite
file directly) and the CSV export matches the store; /metrics, parsed with the Prometheus
client's text parser, equals GetStatistics (`rangexctl status --json`). Screenshots of the
lane view and a fillet page go to OUT_DIR. Every wait is bounded.

usage: dashboard_test.py RANGEXD RANGEXCTL PLANT_YAML OUT_DIR
"""
import csv
import io
import json
import os
import re
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
import urllib.request

from prometheus_client.parser import text_string_to_metric_families
from selenium.webdriver.common.by import By

from browser import headless_chrome, wait_for
from checks import check, fail, terminate

rangexd, rangexctl, plant_yaml, out_dir = sys.argv[1:5]
os.makedirs(out_dir, exist_ok=True)
signal.alarm(600)  # the whole test, whatever hangs


tmp = tempfile.mkdtemp(prefix="rangex-dashboard-")
server = subprocess.Popen(
    [rangexd, "--config", plant_yaml, "--listen", "127.0.0.1:0", "--http", "127.0.0.1:0",
     "--data", os.path.join(tmp, "data")],
    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
grpc_addr = http_addr = None
while grpc_addr is None or http_addr is None:
    line = server.stdout.readline()
    if not line:
        fail("rangexd exited before it served: " + server.stderr.read())
    m = re.search(r"listening on (\S+),", line)
    if m:
        grpc_addr = m.group(1)
    m = re.search(r"dashboard at http://(\S+)/", line)
    if m:
        http_addr = m.group(1)
base = "http://" + http_addr
print("rangexd: gRPC", grpc_addr, "dashboard", base, flush=True)

driver = headless_chrome()
feeder = None
try:
    driver.get(base + "/")
    tiles = wait_for("4 lane tiles", lambda: driver.find_elements(By.CSS_SELECTOR, ".tile")
                     if len(driver.find_elements(By.CSS_SELECTOR, ".tile")) == 4 else None, 20)
    check(len(tiles) == 4, "the lane view shows a tile for each of the 4 lanes")
    wait_for("the live event stream", lambda: "live" in driver.find_element(By.ID, "conn").text, 20)

    # The plant: 4 lanes, a few fillets each, through gRPC while the page watches.
    feeder = subprocess.Popen(
        [rangexctl, "feed", "--server", grpc_addr, "--simulate", "--lanes", "4", "--fillets", "4",
         "--seed", "1"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    first = wait_for("a reject in the live feed",
                     lambda: driver.find_elements(By.CSS_SELECTOR, "#feed-list li"), 240)
    check(len(first) >= 1, "a reject appeared in the live feed")
    # Lights while fed: green on every lane that has lines.
    time.sleep(2.5)
    # Read in one script: the tiles are drawn anew on every refresh, and an element found
    # before a refresh is stale after it (StaleElementReferenceException once in CI).
    lights = driver.execute_script(
        "return Array.from(document.querySelectorAll('.tile'), t => t.getAttribute('data-light'))")
    check(all(l == "green" for l in lights), "every fed lane's light is green (%s)" % lights)
    driver.save_screenshot(os.path.join(out_dir, "dashboard-lanes.png"))
    check(feeder.wait(timeout=300) == 0, "the simulated plant was fed: " + feeder.stderr.read())

    # Every item of the feed arrived after its decision (same machine's clock), and not after
    # a stall. The lag is a figure, not a test of speed: the suite runs on busy machines.
    time.sleep(1.5)
    items = driver.find_elements(By.CSS_SELECTOR, "#feed-list li")
    lags = [int(li.get_attribute("data-shown-ms")) - int(li.get_attribute("data-decided-ns")) / 1e6
            for li in items]
    check(len(lags) >= 1 and min(lags) >= -50 and max(lags) < 60000,
          "each of %d rejects was in the live feed after its decision and without a stall "
          "(lag %.0f-%.0f ms)" % (len(lags), min(lags), max(lags)))

    db = sqlite3.connect(os.path.join(tmp, "data", "rangex.sqlite"))
    stored = {uid: (lane, dec, enc) for uid, lane, dec, enc in
              db.execute("SELECT uid, lane, decision, first_encoder FROM fillets")}
    fed_rejects = {u for u, v in stored.items() if v[1] in ("reject", "not_inspected")}
    shown = {int(li.get_attribute("data-uid")) for li in items}
    check(shown == fed_rejects, "the feed holds exactly the stored rejects (%d)" % len(shown))

    # Opened later, the page shows the stored rejects in its feed.
    driver.refresh()
    wait_for("the stored rejects in a fresh page's feed", lambda: {int(li.get_attribute("data-uid"))
             for li in driver.find_elements(By.CSS_SELECTOR, "#feed-list li")} == fed_rejects, 20)
    check(True, "a page opened later lists the stored rejects in its feed")

    # Two clicks from the lane view to a reject's images: click it in the feed.
    items = driver.find_elements(By.CSS_SELECTOR, "#feed-list li")
    uid = int(items[0].get_attribute("data-uid"))
    items[0].click()
    wait_for("the fillet page", lambda: driver.current_url.endswith("#/fillet/%d" % uid), 10)
    imgs = wait_for("four loaded images", lambda: (lambda ims: ims if len(ims) == 4 and all(
        driver.execute_script("return arguments[0].complete && arguments[0].naturalWidth > 0", i)
        for i in ims) else None)(driver.find_elements(By.CSS_SELECTOR, ".images img")), 20)
    kinds = [f.get_attribute("data-kind") for f in driver.find_elements(By.CSS_SELECTOR, ".images figure")]
    check(kinds == ["xray", "thickness", "pseudo_xray", "residual"],
          "the fillet page shows its X-ray, thickness, pseudo-X-ray and residual (%s)" % kinds)
    frags = db.execute("SELECT COUNT(*) FROM fragments WHERE fillet_uid = ?", (uid,)).fetchone()[0]
    boxes = wait_for("fragment boxes", lambda: driver.find_elements(By.CSS_SELECTOR, ".box")
                     if len(driver.find_elements(By.CSS_SELECTOR, ".box")) == 4 * frags else None, 10) \
        if frags else []
    check(len(boxes) == 4 * frags, "each of its %d fragments is boxed on all four images" % frags)
    rows = driver.find_elements(By.CSS_SELECTOR, "table tr")
    check(len(rows) == frags + 1, "its fragments are listed (%d)" % frags)
    driver.save_screenshot(os.path.join(out_dir, "dashboard-fillet.png"))

    # Records: everything, then the rejects of one lane.
    driver.get(base + "/#/records")
    wait_for("the records table", lambda: len(driver.find_elements(By.CSS_SELECTOR, "#records tbody tr")) ==
             len(stored), 20)
    got = {int(r.get_attribute("data-uid")) for r in driver.find_elements(By.CSS_SELECTOR, "#records tbody tr")}
    check(got == set(stored), "the records search returns every stored fillet (%d)" % len(stored))
    lane = stored[uid][0]
    driver.find_element(By.CSS_SELECTOR, "select[name=lane]").send_keys(str(lane))
    driver.find_element(By.CSS_SELECTOR, "select[name=decision]").send_keys("reject")
    driver.find_element(By.CSS_SELECTOR, "#search button").click()
    want = {u for u, v in stored.items() if v[0] == lane and v[1] == "reject"}
    wait_for("the filtered records", lambda: {int(r.get_attribute("data-uid")) for r in
             driver.find_elements(By.CSS_SELECTOR, "#records tbody tr")} == want, 20)
    check(True, "lane %d's rejects: %d rows, as in the store" % (lane, len(want)))
    href = driver.find_element(By.ID, "csv").get_attribute("href")
    check("lane=%d" % lane in href and "decision=reject" in href, "the export link carries the search")
    export = list(csv.DictReader(io.StringIO(urllib.request.urlopen(
        base + "/api/fillets.csv", timeout=20).read().decode())))
    check(len(export) == len(stored) and all(
        stored[int(r["uid"])] == (int(r["lane"]), r["decision"], int(r["first_encoder"])) for r in export),
        "the CSV export matches the store row by row (%d rows)" % len(export))
    bones = dict(db.execute("SELECT fillet_uid, COUNT(*) FROM fragments WHERE kind = 'bone' GROUP BY fillet_uid"))
    check(all(int(r["bones"]) == bones.get(int(r["uid"]), 0) for r in export),
          "the CSV export's fragment counts match the store")

    # /metrics against GetStatistics, with the browser's event stream still open.
    stats = json.loads(subprocess.run([rangexctl, "status", "--server", grpc_addr, "--json"],
                                      capture_output=True, text=True, timeout=30, check=True).stdout)
    text = urllib.request.urlopen(base + "/metrics", timeout=20).read().decode()
    samples = {}
    for fam in text_string_to_metric_families(text):
        for s in fam.samples:
            samples.setdefault(s.name, []).append(s)

    def total(name, **labels):
        return sum(s.value for s in samples.get(name, [])
                   if all(s.labels.get(k) == v for k, v in labels.items()))

    g = lambda k: int(stats.get(k, 0))
    check(total("rangex_lines_received_total") == g("lines_received"), "lines received = GetStatistics")
    check(total("rangex_lines_processed_total") == g("lines_processed"), "lines processed = GetStatistics")
    check(total("rangex_fillets_total") == g("fillets"), "fillets = GetStatistics (%d)" % g("fillets"))
    check(total("rangex_fillets_total", decision="reject") == g("rejects"), "rejects = GetStatistics")
    check(total("rangex_fillets_total", decision="not_inspected") == g("not_inspected"),
          "not inspected = GetStatistics")
    for r in stats.get("refused", []):
        check(total("rangex_lines_refused_total", code=r["reason"]) == int(r["lines"]),
              "refused %s = GetStatistics" % r["reason"])
    check(total("rangex_verify_mismatches_total") == g("verify_mismatches"), "mismatches = GetStatistics")
    check(total("rangex_queue_capacity_lines") == g("queue_capacity"), "queue capacity = GetStatistics")
    check(total("rangex_subscribers") == g("subscribers") >= 1, "subscribers = GetStatistics")
    check(total("rangex_subscribers_dropped_total") == g("subscribers_dropped"),
          "subscribers that gave way = GetStatistics")
    check(total("rangex_open_files_limit") == g("open_files_limit") > 0,
          "the open-file limit = GetStatistics (%d)" % g("open_files_limit"))
    check(0 < total("rangex_open_files") <= total("rangex_open_files_limit"),
          "open files counted (%d)" % total("rangex_open_files"))
    lat = {l["stage"]: l for l in stats["latencies"]}
    check(total("rangex_decision_latency_seconds_count") == int(lat["last_line_to_decision"]["samples"])
          == g("fillets"), "decision latency histogram counts every decision")
    check(abs(total("rangex_decision_latency_seconds_sum") * 1e3 - lat["last_line_to_decision"]["sum_ms"])
          < 1e-6 * max(1, lat["last_line_to_decision"]["sum_ms"]), "its sum = GetStatistics'")
    check(total("rangex_backend_info", backend=stats["backend"]) == 1, "backend in use as a label")

    # Bad parameters get a clear 400.
    try:
        urllib.request.urlopen(base + "/api/fillets?lane=abc", timeout=10)
        fail("a bad lane parameter was accepted")
    except urllib.error.HTTPError as e:
        check(e.code == 400 and "lane" in json.loads(e.read())["error"], "a bad parameter is a 400 naming it")

    # The calibration history: an upload and a forced activation, with who and when.
    cal = os.path.join(tmp, "cal.yaml")
    with open(cal, "w") as f:
        f.write("laser_plane: {normal: [0, 1, 0], offset_mm: 0.02}\n")
    for args in (["calib", "upload", "--lane", "1", "--id", "cal-7", "--file", cal],
                 ["calib", "activate", "--lane", "1", "--id", "cal-7", "--force"]):
        subprocess.run([rangexctl] + args + ["--server", grpc_addr], check=True, timeout=30,
                       capture_output=True)
    driver.get(base + "/#/calibrations")
    events = wait_for("the calibration history", lambda: [
        [td.text for td in tr.find_elements(By.TAG_NAME, "td")]
        for tr in driver.find_elements(By.CSS_SELECTOR, "#cal-events tr")[1:]] or None, 20)
    audit = db.execute("SELECT who, what FROM audit WHERE what LIKE 'calibration.%' ORDER BY rowid DESC").fetchall()
    check([(e[1], e[2]) for e in events] == [tuple(a) for a in audit] and len(audit) >= 2,
          "the calibration history lists who did what, newest first, as the audit log (%s)" % audit)
    versions = [tr.text for tr in driver.find_elements(By.CSS_SELECTOR, "#cal-versions tr")]
    check(any("cal-7" in v and "active" in v for v in versions), "the activated set shows active")
    driver.save_screenshot(os.path.join(out_dir, "dashboard-calibrations.png"))

    # A verification run started from the lane view: the form posts it, the tile shows it
    # running, the audit records who started it. A bad one shows the server's reason.
    driver.get(base + "/")
    wait_for("the verification form", lambda: driver.find_elements(By.ID, "verify"), 20)
    form = driver.find_element(By.ID, "verify")

    def submit(fields, what, shown):
        for name, value in fields.items():
            form.find_element(By.NAME, name).clear()
            form.find_element(By.NAME, name).send_keys(value)
        form.find_element(By.TAG_NAME, "button").click()
        return wait_for(what, lambda: (lambda t: t if shown in t else None)(
            driver.find_element(By.ID, "verify-out").text), 10)

    out = submit({"lane": "9", "x_mm": "35"}, "the refusal of lane 9", "lane 9")
    check("error" in driver.find_element(By.ID, "verify-out").get_attribute("class"),
          "an unknown lane is refused, the reason shown (%s)" % out)
    out = submit({"lane": "2", "fillets": "3"}, "the started run", "to go")
    check(out == "lane 2: 2 mm calcified sphere, 3 fillets to go", "the run started (%s)" % out)
    wait_for("lane 2's tile showing the run", lambda: "running: 2 mm calcified sphere" in
             driver.execute_script("return document.querySelector('.tile[data-lane=\"2\"]').textContent"), 10)
    who = db.execute("SELECT who, detail FROM audit WHERE what = 'verification.start'").fetchall()
    check(len(who) == 1 and who[0][1].startswith("lane 2:"),
          "the audit records the run's start and who started it (%s)" % who)
    driver.save_screenshot(os.path.join(out_dir, "dashboard-verification.png"))

    # The refused run's 404 is the browser's network log, not the page's error.
    severe = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"
              and "/api/lanes/9/verification" not in e["message"]]
    check(not severe, "no console errors (%s)" % severe)
finally:
    driver.quit()
    if feeder and feeder.poll() is None:
        feeder.kill()
    terminate(server)
print("dashboard: all checks passed; screenshots in", out_dir, flush=True)
