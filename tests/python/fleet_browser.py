#!/usr/bin/env python3
"""The fleet view's dashboard in a real browser (Debian's headless Chromium, Selenium), run by
tests/plant_db_test.sh against `rangexd --fleet` over two servers of two lanes each.

Checks: the page says it is a fleet; the lane tiles are grouped under each server with its
state; a reject of each server opens as SERVER/UID with its images fetched through the server
that keeps them; the records search lists both servers; no console errors. Every wait is
bounded. usage: fleet_browser.py FLEET_URL OUT_DIR
"""
import os
import signal
import sys

from selenium.webdriver.common.by import By

from browser import headless_chrome, wait_for
from checks import check

base, out_dir = sys.argv[1:3]
os.makedirs(out_dir, exist_ok=True)
signal.alarm(240)

driver = headless_chrome()
js = driver.execute_script
try:
    driver.get(base + "/")
    wait_for("two server groups of two tiles", lambda: js(
        "return [...document.querySelectorAll('section.server')].map(s => s.dataset.server + ':' +"
        " s.querySelectorAll('.tile').length).join(' ')") == "srv-a:2 srv-b:2", 20)
    check("fleet of 2 servers" in js("return document.getElementById('plant').textContent"),
          "the header says it is a fleet of 2 servers")
    check(js("return document.getElementById('verify')") is None,
          "no verification form: the fleet only reads")
    check(all("up" in h for h in js("return [...document.querySelectorAll('section.server h3')]"
                                     ".map(h => h.textContent)")), "each server's heading says up")
    driver.save_screenshot(os.path.join(out_dir, "fleet-lanes.png"))
    # The reject feed (read from PostgreSQL): an entry of each server, opened by SERVER/UID.
    wait_for("rejects of both servers in the feed", lambda: js(
        "return new Set([...document.querySelectorAll('#feed-list li')].map(l => l.dataset.server)).size") == 2, 20)
    for server in ("srv-a", "srv-b"):
        item = driver.find_element(By.CSS_SELECTOR, f"#feed-list li[data-server='{server}']")
        uid = item.get_attribute("data-uid")
        item.click()
        wait_for(f"{server}/{uid}'s page", lambda: driver.current_url.endswith(f"#/fillet/{server}/{uid}"), 10)
        loaded = wait_for(f"{server}/{uid}'s images", lambda: js(
            "const i = [...document.querySelectorAll('.frame img')];"
            "return i.length && i.every(x => x.complete && x.naturalWidth > 0) ? i.length : 0"), 20)
        check(loaded >= 3, f"{server}/{uid}: {loaded} images, fetched through {server}")
        check(f"kept by server {server}" in js("return document.getElementById('fillet').textContent"),
              f"{server}/{uid} says which server keeps its images")
        driver.save_screenshot(os.path.join(out_dir, f"fleet-fillet-{server}.png"))
        driver.get(base + "/")
        wait_for("the lane view again", lambda: js("return document.querySelectorAll('#feed-list li').length"), 20)
    driver.get(base + "/#/records")
    servers = wait_for("records of both servers", lambda: js(
        "return [...new Set([...document.querySelectorAll('#records tbody tr td:first-child')]"
        ".map(t => t.textContent))].sort().join(' ')") if js(
        "return document.querySelectorAll('#records tbody tr').length") >= 2 else None, 20)
    check(servers == "srv-a srv-b", "the records search lists both servers (%s)" % servers)
    severe = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    check(not severe, "no console errors (%s)" % severe)
finally:
    driver.quit()
