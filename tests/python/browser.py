"""Debian's headless Chromium under Selenium for the browser tests, and a bounded wait."""
import time

from selenium import webdriver
from selenium.webdriver.chrome.service import Service

from checks import fail


def headless_chrome():
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1500,1100"):
        options.add_argument(a)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    driver.set_page_load_timeout(30)
    return driver


def wait_for(what, f, timeout):
    end = time.time() + timeout
    while time.time() < end:
        v = f()
        if v:
            return v
        time.sleep(0.1)
    fail("timed out after %.0f s waiting for %s" % (timeout, what))
