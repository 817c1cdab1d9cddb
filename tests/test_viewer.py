"""The report's image viewer, driven in a real browser, and its FLIP error maps.

Pages are built by ``experiments.lib.viewer`` from synthetic EXR images and
opened from disk (file://) in Debian's Chromium through Playwright, as a
reader opens ``results/index.html``. What a test sees is compared with what
the images hold: screenshot colours against the sRGB tone map of the EXR
values, the pixel readout against the EXR value, error-map colours against
matplotlib's magma of the relMSE computed here, FLIP against
``flip-evaluator`` called directly. A missing browser fails the tests
(``make dev`` installs it).
"""
import io
import json
import math
import os

import matplotlib
import numpy as np
import pytest
from PIL import Image

from experiments.lib import files
from experiments.lib import metrics, viewer
from experiments.lib import report as report_lib
from tools.ensure_browser import browser_path

W, H = 48, 24
MARK = (31, 9)                 # (x, y) of the marker pixel: pure green in every image
MARK_VALUE = (0.0, 4.0, 0.0)   # HDR green, shown as (0, 255, 0)
BROWSER_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run"]
# Largest difference between matplotlib's magma and the viewer's 17-point table, 8-bit.
MAGMA_TOLERANCE = 6


# ------------------------------------------------------------------ images

def synthetic_images(seed=0):
    """Reference (smooth gradient with an HDR spot), a noisy copy and a checkerboard."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    ref = np.stack([x / W, y / H, np.full_like(x, 0.25)], axis=-1)
    ref[3:6, 3:6] = (7.5, 3.25, 0.125)  # HDR values > 1
    rng = np.random.default_rng(seed)
    noisy = ref * rng.uniform(0.3, 1.7, ref.shape).astype(np.float32)
    checker = np.where(((x // 4 + y // 4) % 2 == 0)[..., None], 0.8, 0.05).astype(np.float32)
    checker = checker * np.array([1.0, 0.7, 0.4], np.float32)
    images = {"reference": ref, "noisy": noisy, "checker": checker}
    for image in images.values():
        image[MARK[1], MARK[0]] = MARK_VALUE
    return images


def tonemap(values):
    return files.tonemap(np.asarray(values, np.float64)).astype(int)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A page with three viewers, built from EXR files; returns (url, EXR images, out dir)."""
    out = str(tmp_path_factory.mktemp("report"))
    exr = {}
    for name, image in synthetic_images().items():
        files.write_exr(os.path.join(out, name + ".exr"), image)
        exr[name] = files.read_exr(os.path.join(out, name + ".exr")).astype(np.float32)
    first = viewer.comparison(out, "first", [("noisy", exr["noisy"]), ("checker", exr["checker"])],
                              reference=exr["reference"], viewer_id="first")
    second = viewer.comparison(out, TRICKY_TITLE,
                               [("checker", exr["checker"]), ("noisy", exr["noisy"])],
                               viewer_id="second")
    far = viewer.comparison(out, "far", [("dim", exr["reference"] * np.float32(0.5))],
                            viewer_id="far")
    body = (first + '<p style="height: 40px">between</p>' + second +
            '<div style="height: 5000px">filler</div>' + far)
    path = viewer.write_page(out, "viewer test", body)
    return "file://" + path, exr, out


@pytest.fixture(scope="module")
def browser():
    path = browser_path()
    if not os.path.isfile(path):
        pytest.fail(f"Chromium not found at {path}: run `make dev` (installs Debian's "
                    f"chromium) or set VR_CHROMIUM")
    from playwright.sync_api import sync_playwright
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=path, headless=True, args=BROWSER_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser, report):
    """The report opened from file://, its first viewer ready; console problems collected."""
    context = browser.new_context(viewport={"width": 1000, "height": 700}, device_scale_factor=1)
    pg = context.new_page()
    pg.set_default_timeout(10_000)
    pg.problems = []
    pg.on("console", lambda m: pg.problems.append(f"{m.type}: {m.text}")
          if m.type in ("error", "warning") else None)
    pg.on("pageerror", lambda e: pg.problems.append(f"pageerror: {e}"))
    pg.goto(report[0])
    pg.wait_for_selector('[data-viewer="first"][data-state="ready"]')
    yield pg
    context.close()


# ----------------------------------------------------------------- helpers

def viewer_el(pg, name="first"):
    return pg.locator(f'[data-viewer="{name}"]')


def canvases(pg, name="first"):
    return viewer_el(pg, name).locator("canvas.vrv-canvas")


def shot(locator) -> np.ndarray:
    """Screenshot of one element as an (h, w, 3) int array."""
    return np.asarray(Image.open(io.BytesIO(locator.screenshot())).convert("RGB")).astype(int)


def view(pg, name="first") -> dict:
    return viewer_el(pg, name).evaluate("el => el.vrViewer.view")


def screen_of(v, x, y):
    """Canvas-local position of the centre of image pixel (x, y)."""
    return v["ox"] + (x + 0.5) * v["s"], v["oy"] + (y + 0.5) * v["s"]


def shown_colours(pg, pixels, name="first", pane=0):
    """Screenshot colours at the centres of image pixels [(x, y), ...]."""
    v = view(pg, name)
    img = shot(canvases(pg, name).nth(pane))
    out = []
    for x, y in pixels:
        sx, sy = screen_of(v, x, y)
        out.append(img[int(sy), int(sx)])
    return np.array(out)


def hover(pg, x, y, name="first", pane=0):
    """Move the mouse over the centre of image pixel (x, y) (scrolling the viewer into view)."""
    pg.wait_for_selector(f'[data-viewer="{name}"][data-state="ready"]')
    canvases(pg, name).nth(pane).scroll_into_view_if_needed()
    box = canvases(pg, name).nth(pane).bounding_box()
    sx, sy = screen_of(view(pg, name), x, y)
    pg.mouse.move(box["x"] + sx, box["y"] + sy)


def wait_attr(pg, attr, value, name="first"):
    pg.wait_for_function(
        "([n, a, v]) => document.querySelector(`[data-viewer=\"${n}\"]`).getAttribute(a) === v",
        arg=[name, attr, value])


def zoom(pg, delta_y, factor, name="first"):
    """Turn the wheel at the mouse; wait until the viewer zoomed by ``factor``."""
    s0 = view(pg, name)["s"]
    pg.mouse.wheel(0, delta_y)
    pg.wait_for_function(f"document.querySelector('[data-viewer=\"{name}\"]').vrViewer.view.s"
                         f" > {0.99 * factor * s0}")
    assert view(pg, name)["s"] == pytest.approx(factor * s0, rel=1e-6)


def readout(pg, name="first"):
    raw = viewer_el(pg, name).get_attribute("data-readout")
    return json.loads(raw) if raw else None


def green_box(img):
    """Bounding box (x0, y0, x1, y1) of the pure-green marker in a screenshot, or None."""
    ys, xs = np.nonzero((img[..., 0] == 0) & (img[..., 1] == 255) & (img[..., 2] == 0))
    if xs.size == 0:
        return None
    return xs.min(), ys.min(), xs.max() + 1, ys.max() + 1


TRICKY_TITLE = 'second </script> & "quotes" <b>'
SAMPLE = [(0, 0), (5, 4), (17, 11), (30, 20), (47, 23), (40, 2), MARK]


# ------------------------------------------------------------------- tests

def test_opens_from_file_without_console_errors_and_lazy_loads(page, report):
    assert report[0].startswith("file://")
    # the viewer below the fold has not loaded its data scripts
    assert viewer_el(page, "far").get_attribute("data-state") == "idle"
    far_src = json.loads(viewer_el(page, "far").locator("script.vrv-manifest").text_content())
    far_src = far_src["images"][0]["data"]["src"]
    loaded = page.evaluate("Array.from(document.scripts, s => s.getAttribute('src'))")
    assert far_src not in loaded
    viewer_el(page, "far").scroll_into_view_if_needed()
    page.wait_for_selector('[data-viewer="far"][data-state="ready"]')
    assert far_src in page.evaluate("Array.from(document.scripts, s => s.getAttribute('src'))")
    # titles are text, never markup (the manifest JSON survives "</script>")
    assert viewer_el(page, "second").locator(".vrv-title").text_content() == TRICKY_TITLE
    assert page.problems == []


def test_missing_data_is_reported(browser, report, tmp_path):
    """Negative control of the console check: a viewer whose data script is gone fails loudly."""
    exr = report[1]
    html = viewer.comparison(str(tmp_path), "broken", [("noisy", exr["noisy"] * 2)],
                             viewer_id="broken")
    path = viewer.write_page(str(tmp_path), "broken", html)
    for name in os.listdir(tmp_path / viewer.DATA_DIR):
        os.remove(tmp_path / viewer.DATA_DIR / name)
    pg = browser.new_page()
    problems = []
    pg.on("console", lambda m: problems.append(m.text) if m.type == "error" else None)
    pg.goto("file://" + path)
    pg.wait_for_selector('[data-viewer="broken"][data-state="failed"]')
    assert any("viewer data missing" in p for p in problems), problems
    pg.close()


def test_shows_the_exr_pixels_and_key_2_switches_the_image(page, report):
    exr = report[1]
    before = shot(canvases(page).first)
    expected = tonemap([exr["noisy"][y, x] for x, y in SAMPLE])
    assert np.abs(shown_colours(page, SAMPLE) - expected).max() <= 1
    hover(page, 10, 10)
    page.keyboard.press("2")
    wait_attr(page, "data-drawn", "image:1")
    after = shot(canvases(page).first)
    assert np.mean(np.any(before != after, axis=-1)) > 0.5  # most displayed pixels changed
    expected = tonemap([exr["checker"][y, x] for x, y in SAMPLE])
    assert np.abs(shown_colours(page, SAMPLE) - expected).max() <= 1
    # labels are clickable; Space flips between the last two picked
    viewer_el(page).locator('.vrv-label[data-index="2"]').click()
    wait_attr(page, "data-drawn", "image:2")
    hover(page, 10, 10)
    page.keyboard.press(" ")
    wait_attr(page, "data-drawn", "image:1")
    page.keyboard.press(" ")
    wait_attr(page, "data-drawn", "image:2")
    assert page.problems == []


def test_keys_act_on_the_viewer_under_the_mouse_else_the_last_clicked(page):
    canvases(page, "first").first.click()
    hover(page, 5, 5, name="second")  # the mouse wins over the last click
    page.keyboard.press("2")
    wait_attr(page, "data-selected", "1", name="second")
    assert viewer_el(page, "first").get_attribute("data-selected") == "0"
    page.mouse.move(2, 2)  # off every viewer: keys go to the last one clicked
    page.keyboard.press("2")
    wait_attr(page, "data-selected", "1", name="first")
    page.keyboard.press("1")
    wait_attr(page, "data-selected", "0", name="first")
    assert viewer_el(page, "second").get_attribute("data-selected") == "1"


def test_wheel_zooms_around_the_cursor_with_nearest_pixels(page):
    box0 = green_box(shot(canvases(page).first))
    assert box0 is not None
    width0 = box0[2] - box0[0]
    assert width0 == pytest.approx(view(page)["s"], abs=1)  # one image pixel at fit zoom
    hover(page, *MARK)
    zoom(page, -400, 4)  # 2 stops of zoom: 4x
    img = shot(canvases(page).first)
    x0, y0, x1, y1 = green_box(img)
    assert x1 - x0 == pytest.approx(4 * width0, abs=2)
    assert y1 - y0 == pytest.approx(4 * width0, abs=2)
    # nearest-neighbour: the magnified pixel is one flat colour, no smoothing at its edges
    assert (img[y0:y1, x0:x1] == [0, 255, 0]).all()
    # zoom around the cursor: the marker stays under the mouse (and in the readout)
    sx, sy = screen_of(view(page), *MARK)
    assert x0 <= sx < x1 and y0 <= sy < y1
    assert (readout(page)["x"], readout(page)["y"]) == MARK


def test_drag_pans_and_the_view_is_shared_by_every_image(page):
    hover(page, 10, 10)
    page.keyboard.press("g")  # side by side: one pane per image
    wait_attr(page, "data-layout", "grid")
    page.wait_for_function("document.querySelector('[data-viewer=\"first\"]').dataset.drawn"
                           ".split(',').length === 3")
    hover(page, *MARK, pane=1)
    zoom(page, -200, 2)
    boxes = [green_box(shot(canvases(page).nth(i))) for i in range(3)]
    assert boxes[0] is not None and boxes[0] == boxes[1] == boxes[2]
    # drag in the third pane moves every pane's content by the same amount
    box = canvases(page).nth(2).bounding_box()
    start = (box["x"] + 40, box["y"] + 40)
    page.mouse.move(*start)
    page.mouse.down()
    page.mouse.move(start[0] - 30, start[1] + 20, steps=5)
    page.mouse.up()
    moved = [green_box(shot(canvases(page).nth(i))) for i in range(3)]
    assert moved[0] == moved[1] == moved[2]
    assert (moved[0][0] - boxes[0][0], moved[0][1] - boxes[0][1]) == (-30, 20)


def test_pixel_readout_equals_the_exr_value(page, report):
    exr = report[1]
    for x, y in [(4, 4), (0, 0), MARK, (47, 23), (22, 13)]:
        hover(page, x, y)
        page.wait_for_function("([x, y]) => { const r = document.querySelector("
                               "'[data-viewer=\"first\"]').dataset.readout; "
                               "return r && JSON.parse(r).x === x && JSON.parse(r).y === y; }",
                               arg=[x, y])
        r = readout(page)
        assert r["image"] == 0
        assert np.array_equal(np.float32(r["rgb"]), exr["noisy"][y, x])  # exact float32
        text = viewer_el(page).locator(".vrv-readout").text_content()
        assert f"({x}, {y})" in text
    # after zoom and pan the readout still names the pixel under the cursor
    hover(page, 4, 4)
    zoom(page, -600, 8)
    hover(page, 5, 4)
    page.wait_for_function("JSON.parse(document.querySelector('[data-viewer=\"first\"]')"
                           ".dataset.readout).x === 5")
    assert np.array_equal(np.float32(readout(page)["rgb"]), exr["noisy"][4, 5])
    assert exr["noisy"][4, 5].max() > 1  # an HDR value, read out unclipped


def test_exposure_in_stops(page, report):
    exr = report[1]
    hover(page, 10, 10)
    page.keyboard.press("+")
    wait_attr(page, "data-exposure", "1")
    expected = tonemap([2 * exr["noisy"][y, x] for x, y in SAMPLE])
    assert np.abs(shown_colours(page, SAMPLE) - expected).max() <= 1
    page.keyboard.press("-")
    page.keyboard.press("-")
    wait_attr(page, "data-exposure", "-1")
    expected = tonemap([0.5 * exr["noisy"][y, x] for x, y in SAMPLE])
    assert np.abs(shown_colours(page, SAMPLE) - expected).max() <= 1


def test_e_shows_the_relmse_map_and_m_the_flip_map(page, report):
    exr = report[1]
    manifest = json.loads(viewer_el(page).locator("script.vrv-manifest").text_content())
    lo, hi = manifest["ranges"]["relmse"]
    rel = metrics.relmse_map(exr["noisy"], exr["reference"])
    hover(page, 17, 11)
    page.keyboard.press("e")
    wait_attr(page, "data-drawn", "error:relmse:0")
    assert viewer_el(page).locator(".vrv-colorbar").is_visible()
    points = [p for p in SAMPLE if p != MARK] + [(20, 20)]
    t = [(math.log10(rel[y, x]) - lo) / (hi - lo) if rel[y, x] > 0 else 0 for x, y in points]
    expected = np.round(matplotlib.colormaps["magma"](np.clip(t, 0, 1))[:, :3] * 255)
    assert np.abs(shown_colours(page, points) - expected).max() <= MAGMA_TOLERANCE
    # the marker is exact in both images: zero error, the colour map's darkest colour
    assert np.abs(shown_colours(page, [MARK])[0] - [0, 0, 4]).max() <= 1
    r = readout(page)
    assert r["metric"] == "relmse" and r["error"] == float(np.float16(rel[11, 17]))  # f16 map
    page.keyboard.press("m")
    wait_attr(page, "data-drawn", "error:flip:0")
    import flip_evaluator
    direct, _, _ = flip_evaluator.evaluate(exr["reference"], exr["noisy"], "HDR", applyMagma=False)
    page.wait_for_function("JSON.parse(document.querySelector('[data-viewer=\"first\"]')"
                           ".dataset.readout).metric === 'flip'")
    assert readout(page)["error"] == float(np.float16(direct[11, 17, 0]))
    expected = np.round(matplotlib.colormaps["magma"](
        np.array([direct[y, x, 0] for x, y in points]))[:, :3] * 255)
    assert np.abs(shown_colours(page, points) - expected).max() <= MAGMA_TOLERANCE
    page.keyboard.press("e")
    wait_attr(page, "data-drawn", "image:0")
    assert not viewer_el(page).locator(".vrv-colorbar").is_visible()
    assert page.problems == []


def test_report_of_a_small_run_opens_with_working_viewers(browser, tmp_path):
    """A real (tiny) convergence run: its report's viewers load from file://, and the
    FLIP column of the error table is the mean of the FLIP map the viewer shows."""
    from experiments.lib.studies import convergence
    out = tmp_path / "r"
    convergence.STUDY.main(["--resolution", "16x8", "--reference-spp", "8", "--spp", "4",
                      "--time-budget", "0.02", "--methods", "uniform,bsdf", "--out", str(out)])
    page_html = (out / "index.html").read_text()
    assert 'href="viewer.css"' in page_html and 'src="viewer.js"' in page_html
    assert "viewer-data/" not in "".join(report_lib.produced_files(str(out)))
    header = (out / "convergence" / "errors.csv").read_text().splitlines()[0].split(",")
    assert {"MSE", "relMSE", "FLIP (first repeat)"} <= set(header)
    pg = browser.new_page(viewport={"width": 1000, "height": 700})
    problems = []
    pg.on("console", lambda m: problems.append(m.text) if m.type in ("error", "warning") else None)
    pg.on("pageerror", lambda e: problems.append(str(e)))
    pg.goto("file://" + str(out / "index.html"))
    roots = pg.locator("[data-viewer]")
    assert roots.count() == 4  # every method at 4 spp, one sequence per method, equal time
    for i in range(roots.count()):
        roots.nth(i).scroll_into_view_if_needed()
        pg.wait_for_function("el => el.dataset.state === 'ready'",
                             arg=roots.nth(i).element_handle())
    manifest = json.loads(roots.nth(1).locator("script.vrv-manifest").text_content())
    assert [im["label"] for im in manifest["images"]] == ["1 spp", "2 spp", "4 spp", "reference"]
    image = files.read_exr(str(out / "convergence" / "uniform" / "spp00004.exr"))
    ref = viewer.read_blob(str(out), manifest["images"][-1]["data"], image.shape)
    flip_map = viewer.read_blob(str(out), manifest["images"][2]["errors"]["flip"], image.shape[:2])
    row = next(r.split(",") for r in (out / "convergence" / "errors.csv").read_text().splitlines()
               if r.startswith("uniform,4,"))
    assert float(row[header.index("FLIP (first repeat)")]) == pytest.approx(metrics.flip_mean(image, ref),
                                                           rel=2e-3)  # 3 digits
    assert flip_map.mean() == pytest.approx(metrics.flip_mean(image, ref), rel=1e-3)  # f16 map
    assert problems == []
    pg.close()


# ------------------------------------------------------ FLIP, data files

def test_flip_of_an_image_against_itself_is_zero():
    image = synthetic_images()["noisy"]
    error, mean = metrics.flip(image, image)
    assert mean == 0.0 and error.shape == (H, W) and not error.any()


def test_flip_matches_flip_evaluator():
    import flip_evaluator
    images = synthetic_images(seed=3)
    error, mean = metrics.flip(images["noisy"], images["reference"])
    direct, direct_mean, _ = flip_evaluator.evaluate(images["reference"], images["noisy"], "HDR",
                                                     applyMagma=False)
    assert np.array_equal(error, direct[..., 0])
    assert mean == pytest.approx(direct_mean, rel=1e-12) and mean > 0.05
    error[:] = 1  # the caller's copy: a second call (served from the cache) is unchanged
    again, mean_again = metrics.flip(images["noisy"], images["reference"])
    assert np.array_equal(again, direct[..., 0]) and mean_again == mean
    assert metrics.errors(images["noisy"], images["reference"])["flip"] == mean
    # more noise, more FLIP
    _, worse = metrics.flip(images["checker"], images["reference"])
    assert worse > mean
    with pytest.raises(ValueError, match=r"\(24, 48, 3\).*\(24, 47, 3\)"):
        metrics.flip(images["noisy"], images["reference"][:, :47])


def test_relmse_map_averages_to_metrics_relmse():
    images = synthetic_images(seed=5)
    rel = metrics.relmse_map(images["noisy"], images["reference"])
    expected = metrics.relmse(images["noisy"], images["reference"])
    assert rel.mean() == pytest.approx(expected, rel=1e-12)


def test_data_files_round_trip_and_are_shared(tmp_path):
    image = synthetic_images()["noisy"]
    a = viewer.write_blob(str(tmp_path), image)
    b = viewer.write_blob(str(tmp_path), image.copy())
    assert a == b and len(os.listdir(tmp_path / viewer.DATA_DIR)) == 1
    assert np.array_equal(viewer.read_blob(str(tmp_path), a, image.shape), image)
    c = viewer.write_blob(str(tmp_path), image.reshape(W, H, 3))
    assert c["id"] != a["id"]
    half = viewer.write_blob(str(tmp_path), image * 1e5, "f16")  # clipped to the f16 range
    back = viewer.read_blob(str(tmp_path), half, image.shape)
    expected = np.minimum(image * 1e5, 65504).astype(np.float16).astype(np.float32)
    assert np.array_equal(back, expected)
    with pytest.raises(ValueError, match=r"unknown data type 'f64'.*\['f16', 'f32'\]"):
        viewer.write_blob(str(tmp_path), image, "f64")


def test_bad_comparisons_raise_clear_errors(tmp_path):
    images = synthetic_images()
    with pytest.raises(ValueError, match="no images"):
        viewer.comparison(str(tmp_path), "t", [])
    with pytest.raises(ValueError, match=r"image 'b' has shape \(24, 47, 3\)"):
        viewer.comparison(str(tmp_path), "t", [("a", images["noisy"]),
                                               ("b", images["noisy"][:, :47])])
    with pytest.raises(ValueError, match=r"must be \(H, W, 3\)"):
        viewer.comparison(str(tmp_path), "t", [("a", images["noisy"][..., 0])])
