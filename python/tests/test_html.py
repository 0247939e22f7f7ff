"""The HTML report from Python (``analyze(..., html=)``, ``simplify(..., html=)``): the file is
written, its data lists every handle the call returned, the input is untouched, a bad path is
refused before any work. (The page itself runs in Chromium under scripts/test_report.sh.)"""

import base64
import gzip
import json
import math
import re

import numpy as np
import pytest

import isotopo
from conftest import SAMPLE, noise, torus


def report_data(path):
    """The report's JSON, decoded as the page decodes it."""
    text = path.read_text()
    packed = re.search(r'id="report-data">(.*?)</script>', text, re.S).group(1)
    return json.loads(gzip.decompress(base64.b64decode(packed.strip())))


def test_analyze_writes_a_report_of_every_handle(tmp_path):
    vol = noise(np.random.default_rng(3), (28, 26, 24))
    before = vol.copy()
    out = tmp_path / "report.html"
    handles = isotopo.analyze(vol, 0.5, html=out)
    assert len(handles) > 5
    d = report_data(out)
    assert d["kind"] == "analyze"
    assert d["handle_count"] == len(handles)
    assert sorted(h["id"] for h in d["handles"]) == sorted(h.id for h in handles)
    assert d["title"] == "array 28 × 26 × 24"
    assert np.array_equal(vol, before)


def test_a_loaded_file_names_the_report(tmp_path):
    vol = isotopo.load(SAMPLE)
    out = tmp_path / "mni.html"
    handles = isotopo.analyze(vol, 127.5, tau=8, html=str(out))
    d = report_data(out)
    assert d["title"] == "mni2009a-gm.nii.gz"
    assert d["handle_count"] == len(handles) == 706


def test_simplify_writes_a_report_of_the_handles_removed_and_kept(tmp_path):
    vol = torus()
    out = tmp_path / "s.html"
    result, report = isotopo.simplify(vol, 0.0, math.inf, html=out)
    d = report_data(out)
    assert d["kind"] == "simplify"
    assert d["handle_count"] == sum(r["handles"] for r in report.removed) + len(report.kept) == 1
    assert d["handles"][0]["status"] in ("collapse", "pinch")
    assert d["handles"][0]["wall"], "the wall's samples"


def test_a_report_into_a_missing_folder_is_refused_before_the_work(tmp_path):
    with pytest.raises((OSError, ValueError), match="output directory .* does not exist"):
        isotopo.analyze(torus(), 0.0, html=tmp_path / "missing" / "r.html")
    with pytest.raises(TypeError):
        isotopo.simplify(torus(), 0.0, 10, html=3.5)
