"""The HTML report in headless Chromium: no console errors, every image decoded, tables complete.

Selenium drives Debian's chromium with the driver path given explicitly, so Selenium
Manager never tries to download a browser or a driver (the machine has no network).
A screenshot of the whole page is left under PARAMBENCH_TEST_ARTIFACTS.
"""

import os

import pytest

pytestmark = [pytest.mark.browser, pytest.mark.slow]

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
_ARGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
         "--window-size=1400,1000")


@pytest.fixture(scope="module")
def driver(require_tool):
    require_tool("chromium")
    require_tool("chromedriver")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        message = "selenium is not installed; install the test extra: pip install -e '.[test]'"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)

    os.environ.setdefault("SE_OFFLINE", "true")  # belt and braces: Selenium Manager must stay offline
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in _ARGS:
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    browser = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    browser.set_page_load_timeout(60)
    yield browser
    browser.quit()


def open_report(driver, path):
    driver.get(path.resolve().as_uri())
    driver.execute_script("return document.readyState")  # get() waits for load; this syncs the driver
    return driver


def severe_console_messages(driver):
    return [entry for entry in driver.get_log("browser") if entry.get("level") in ("SEVERE", "ERROR")]


def row_counts(driver):
    return driver.execute_script(
        "const out = {};"
        "for (const t of document.querySelectorAll('table')) {"
        "  const k = t.className || 'plain';"
        "  out[k] = (out[k] || 0) + t.querySelectorAll('tbody tr').length; }"
        "return out;")


def test_report_opens_cleanly_with_decoded_images(driver, built_report, artifacts_dir):
    open_report(driver, built_report["paths"]["html"])
    assert driver.title == "parambench report"
    assert severe_console_messages(driver) == []
    images = driver.execute_script(
        "return Array.from(document.images).map(i => [i.alt, i.complete, i.naturalWidth, i.naturalHeight]);")
    assert len(images) >= 12
    for alt, complete, width, height in images:
        assert complete and width > 0 and height > 0, alt
    # nothing was fetched: data URIs only
    fetched = driver.execute_script(
        "return performance.getEntriesByType('resource').map(e => e.name).filter(n => !n.startsWith('data:'));")
    assert fetched == []
    counts = row_counts(driver)
    assert counts["summary"] == 9
    assert counts["failures"] == 1
    assert counts["overview"] == 3
    assert counts["benchmarks"] == 3
    assert counts["exponents"] == 3
    assert counts["metadata"] >= 8
    best = driver.execute_script("return document.querySelectorAll('table.summary td.best').length;")
    assert best >= 9
    # full-page screenshot for people to look at
    height = driver.execute_script("return document.documentElement.scrollHeight;")
    driver.set_window_size(1400, min(int(height) + 100, 16000))
    shot = artifacts_dir / "report-full-page.png"
    assert driver.save_screenshot(str(shot)) and shot.stat().st_size > 10_000
    driver.set_window_size(1400, 1000)


def test_partial_report_opens_cleanly(driver, tmp_path, make_results, spec_type, artifacts_dir):
    from parambench.reports.build import build_report

    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"saddle": [144]}, methods=("ocp", "lscm"), seeds=(0,),
                                 failed=(("ocp", "saddle", 0),)))
    path = build_report(root, formats=("html",))["html"]
    open_report(driver, path)
    assert severe_console_messages(driver) == []
    counts = row_counts(driver)
    assert counts["summary"] == 2 and counts["failures"] == 1
    status = driver.execute_script(
        "return Array.from(document.querySelectorAll('table.summary td.status.failed')).map(td => td.textContent);")
    assert len(status) == 1 and "ConvergenceError" in status[0]
    assert driver.execute_script("return Array.from(document.images).every(i => i.naturalWidth > 0);")
    driver.save_screenshot(str(artifacts_dir / "report-partial.png"))


def test_the_checks_catch_a_broken_page(driver, tmp_path):
    # The harness itself: a missing image and a script error must show up, or the tests above prove nothing.
    page = tmp_path / "broken.html"
    page.write_text('<!DOCTYPE html><html><head><link rel="icon" href="data:,"></head><body>'
                    '<img src="missing.png"><script>undefinedFunction();</script></body></html>')
    open_report(driver, page)
    assert len(severe_console_messages(driver)) >= 1
    assert driver.execute_script("return document.images[0].naturalWidth;") == 0


def _column(driver, table_css, index):
    return driver.execute_script(
        "return Array.from(document.querySelector(arguments[0]).tBodies[0].rows)"
        ".filter(r => !r.hidden).map(r => r.cells[arguments[1]].textContent);", table_css, index)


def test_a_click_on_a_header_sorts_the_table(driver, built_report):
    open_report(driver, built_report["paths"]["html"])
    table = "table.summary"
    qc = driver.execute_script(
        "return Array.from(document.querySelector('table.summary').tHead.rows[0].cells)"
        ".map(c => c.textContent).indexOf('QC mean');")
    before = _column(driver, table, qc)
    header = driver.execute_script("return document.querySelector('table.summary').tHead.rows[0].cells[arguments[0]];",
                                   qc)
    header.click()
    ascending = _column(driver, table, qc)
    assert ascending != before or before == sorted(before, key=float)
    assert [float(v) for v in ascending] == sorted(float(v) for v in before)
    assert header.get_attribute("aria-sort") == "ascending"
    header.click()
    descending = _column(driver, table, qc)
    assert [float(v) for v in descending] == sorted((float(v) for v in before), reverse=True)
    assert header.get_attribute("aria-sort") == "descending"
    # a text column sorts too: the method names come out in order
    driver.execute_script("document.querySelector('table.summary').tHead.rows[0].cells[0].click();")
    names = _column(driver, table, 0)
    assert names == sorted(names)
    assert severe_console_messages(driver) == []


def test_the_filter_box_hides_rows_without_the_text(driver, built_report):
    open_report(driver, built_report["paths"]["html"])
    box = driver.execute_script("return document.querySelector('table.summary').previousElementSibling;")
    assert "table-filter" in box.get_attribute("class")
    box.send_keys("ocp")
    names = _column(driver, "table.summary", 0)
    assert names == ["ocp"]
    for _ in range(3):
        box.send_keys("\b")
    assert len(_column(driver, "table.summary", 0)) == 3


def test_a_click_on_a_summary_row_opens_its_pictures(driver, built_report, artifacts_dir):
    open_report(driver, built_report["paths"]["html"])
    detail = driver.find_element("id", "detail")
    assert not detail.is_displayed()
    # a surface with pictures (bump is drawn at its 400-point size, so not every table has them)
    config = driver.execute_script("return document.querySelector('img[data-panels]').getAttribute('data-config');")
    row = driver.execute_script(
        "return Array.from(document.querySelectorAll('table.summary tr[data-variant=\"ocp\"]'))"
        ".find(r => r.getAttribute('data-config') === arguments[0]);", config)
    driver.execute_script("arguments[0].scrollIntoView(); arguments[0].cells[2].click();", row)
    assert detail.is_displayed()
    assert detail.find_element("tag name", "h3").text == f"ocp — {config}"
    crops = driver.execute_script(
        "return Array.from(document.querySelectorAll('#detail .crop')).map(d => "
        "[d.style.backgroundImage.slice(0, 20), d.offsetWidth, d.offsetHeight]);")
    # the uv layout and the checkerboard of that surface, cut from the figures already in the page
    assert len(crops) == 2
    for image, width, height in crops:
        assert image.startswith('url("data:image/') and 160 <= width <= 324 and height > 100  # + border
    driver.save_screenshot(str(artifacts_dir / "report-detail-view.png"))
    driver.execute_script("document.dispatchEvent(new KeyboardEvent('keydown', {key: 'Escape'}));")
    assert not detail.is_displayed()
    # a surface drawn at another size has no pictures: the view says so instead of showing nothing
    other = driver.execute_script(
        "return Array.from(document.querySelectorAll('table.summary tr[data-variant]'))"
        ".find(r => !document.querySelector('img[data-config=\"' + r.getAttribute('data-config') + '\"]'));")
    driver.execute_script("arguments[0].cells[0].click();", other)
    assert detail.is_displayed() and "No picture of this cell" in detail.text
    assert severe_console_messages(driver) == []
