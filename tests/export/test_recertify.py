"""An export of a packing edited after it was certified certifies it again first
(`export/recertify.py`)."""

from __future__ import annotations

import json

import pytest
from testdata import mesh_path

from jampacked.core.api import pack
from jampacked.core.errors import InputError
from jampacked.core.packing_digest import DIGEST, placements_status
from jampacked.core.packing_json import load_packing, save_packing
from jampacked.export.assemble import export_packing

LEMON = mesh_path("fruit/ycb_lowpoly/014_lemon.obj")


@pytest.fixture(scope="module")
def packed(tmp_path_factory):
    d = tmp_path_factory.mktemp("recertify")
    p = pack("box:30x30x30", [str(LEMON)], type_scale=300.0, seed=1)
    assert p.n >= 3 and p.certificate["certified"]
    path = d / "packing.json"
    save_packing(p, path)
    return d, path


def _edited(d, path, name, edit):
    doc = json.loads(path.read_text())
    edit(doc)
    out = d / f"{name}.json"
    out.write_text(json.dumps(doc))
    return out


def _onto_the_next(doc):
    # object 0 put where object 1 is
    p0, p1 = doc["placements"][0], doc["placements"][1]
    p0["translation"] = list(p1["translation"])
    for r in range(3):
        p0["matrix"][r][3] = p1["translation"][r]


def test_a_packing_records_the_digest_of_what_it_certified(packed):
    d, path = packed
    p = load_packing(path)
    assert isinstance(p.certificate[DIGEST], str)
    assert placements_status(p) == "as certified"
    assert placements_status(load_packing(_edited(d, path, "moved", _onto_the_next))) \
        == "changed"

    # the inputs' clearance, which parts mode trusts, is not in the digest: a packing made
    # without one read "as certified" with 0.5 written in
    def clearance(doc):
        doc["inputs"]["clearance"] = 0.5

    assert placements_status(load_packing(_edited(d, path, "clearance", clearance))) \
        == "changed"


def test_an_edit_that_makes_objects_overlap_is_refused_by_name(packed, tmp_path):
    # the export wrote a valid union of two lemons in one place, as if certified
    d, path = packed
    edited = _edited(d, path, "overlap", _onto_the_next)
    with pytest.raises(InputError, match=r"changed after it was certified.*object 0 "
                       r"\(014_lemon\) and object 1 \(014_lemon\)") as err:
        export_packing(edited, tmp_path / "out.stl")
    assert "Undo the edit, or pack again" in str(err.value)
    assert not (tmp_path / "out.stl").exists()


def test_an_edit_that_keeps_the_packing_sound_exports_with_a_note(packed, tmp_path):
    # removing objects leaves the rest as certified: checked again, then exported
    d, path = packed

    def cut(doc):
        doc["placements"] = doc["placements"][:2]

    edited = _edited(d, path, "cut", cut)
    rep = export_packing(edited, tmp_path / "out.stl")
    assert rep.objects == 2 and rep.bodies >= 1
    assert any("certified again before export" in w for w in rep.warnings)
    rep = export_packing(path, tmp_path / "whole.stl")  # as written: no note, no check
    assert not any("certified again" in w for w in rep.warnings)


def test_a_failure_by_clearance_is_named_by_its_shortfall(packed):
    # a pair failing on its gap alone read "overlapping by 0 of the smaller", a wall gap
    # "0 of it outside", and the pair named could be one within the tolerance
    from jampacked.core.certify import CertifyReport
    from jampacked.export.recertify import _failures

    p = load_packing(packed[1])
    rep = CertifyReport(certified=False, tol=1e-4, clearance=0.5, worst_overlap=5e-5,
                        worst_overlap_pair=(0, 2), worst_outside=0.0,
                        worst_outside_object=None, min_pair_gap=0.38, min_wall_gap=0.41,
                        bad_pairs=[(0, 1)], bad_wall=[2], pair_shortfall={(0, 1): 0.12},
                        wall_shortfall={2: 0.09})
    msg = _failures(p, rep)
    assert "1 pair fails (worst: object 0 (014_lemon) and object 1 (014_lemon) are 0.38 " \
           "apart (0.12 under the clearance 0.5))" in msg
    assert "1 object fails at the wall (worst: object 2 (014_lemon) is 0.41 from the wall " \
           "(0.09 under the clearance 0.5))" in msg
    assert "overlap" not in msg and "outside" not in msg
    # a clearance written into a packing made without one: the pair touches ("are 0.5
    # closer than the clearance 0.5")
    rep.pair_shortfall, rep.wall_shortfall = {(0, 1): 0.5}, {2: 0.5}
    msg = _failures(p, rep)
    assert "object 0 (014_lemon) and object 1 (014_lemon) touch (the clearance is 0.5)" in msg
    assert "object 2 (014_lemon) touches the wall (the clearance is 0.5)" in msg


def test_an_edited_packing_being_certified_again_can_be_cancelled(packed, tmp_path):
    from jampacked.core.errors import Cancelled

    d, path = packed
    edited = _edited(d, path, "cancel", _onto_the_next)
    seen = []
    with pytest.raises(Cancelled):
        export_packing(edited, tmp_path / "out.stl", progress=lambda f, m: seen.append(m),
                       should_cancel=lambda: any("certifying the packing again" in m for m in seen))
    assert not (tmp_path / "out.stl").exists()


def _no_digest(doc):
    del doc["certificate"][DIGEST]


def test_a_packing_that_says_it_is_certified_without_a_digest_is_certified_again(
        packed, tmp_path):
    # with its digest deleted an edited packing read as one written before digests, and
    # its two lemons in one place were exported as a valid union
    d, path = packed

    def moved(doc):
        _no_digest(doc)
        _onto_the_next(doc)

    with pytest.raises(InputError, match=r"records no digest of what was certified.*"
                       r"object 0 \(014_lemon\) and object 1 \(014_lemon\)"):
        export_packing(_edited(d, path, "no-digest-moved", moved), tmp_path / "out.stl")
    assert not (tmp_path / "out.stl").exists()
    rep = export_packing(_edited(d, path, "no-digest", _no_digest), tmp_path / "out.stl")
    assert rep.passed
    assert any("records no digest" in w and "certified again before export" in w
               for w in rep.warnings)


def test_an_edited_volume_is_named_as_an_edit(packed, tmp_path):
    # it read "packed by a version that read the file differently"
    d, path = packed

    def volume(doc):
        doc["types"][0]["volume"] *= 1.5

    with pytest.raises(InputError, match=r"edited after it was certified") as err:
        export_packing(_edited(d, path, "volume", volume), tmp_path / "out.stl")
    assert "version" not in str(err.value)


def test_a_packing_that_does_not_say_it_is_certified_is_checked_and_named(packed, tmp_path):
    # with its digest removed and "certified" set to false, two lemons in one place were
    # exported as a valid union with no word
    d, path = packed

    def uncertified(doc):
        _no_digest(doc)
        doc["certificate"]["certified"] = False
        _onto_the_next(doc)

    rep = export_packing(_edited(d, path, "uncertified", uncertified), tmp_path / "out.stl")
    (note,) = rep.warnings
    assert "is not certified" in note and "object 0 (014_lemon) and object 1 (014_lemon) " \
        "overlap" in note and "exported as it is" in note

    def sound(doc):
        doc["certificate"] = {}

    rep = export_packing(_edited(d, path, "no-certificate", sound), tmp_path / "sound.stl")
    assert rep.passed and rep.warnings == []  # checked, and nothing to say


def test_a_smaller_clearance_asked_keeps_the_packing_as_certified(tmp_path):
    # a packing certified with 0.5 whose inputs ask 0 read "no longer certified" (info
    # exited 1) and was certified again at export; a larger one is a change
    p = pack("box:24x24x24", [str(LEMON)], type_scale=300.0, seed=1, clearance=0.5,
             fidelity="low", time_budget=2.0)
    assert p.certificate["certified"] and p.certificate["clearance"] == 0.5
    path = tmp_path / "c.json"
    save_packing(p, path)

    def asked(value):
        doc = json.loads(path.read_text())
        doc["inputs"]["clearance"] = value
        out = tmp_path / f"c{value}.json"
        out.write_text(json.dumps(doc))
        return load_packing(out)

    assert placements_status(asked(0.0)) == "as certified"
    assert placements_status(asked(0.3)) == "as certified"
    assert placements_status(asked(0.7)) == "changed"
