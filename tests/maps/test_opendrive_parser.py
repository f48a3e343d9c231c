"""Parsing edge cases: bad input names the file, micro roads, namespaces, text input."""

from __future__ import annotations

import pytest

from b2d_data.maps import OpenDriveError, load_opendrive, parse_opendrive

_MICRO = """<OpenDRIVE xmlns="http://code.asam.net/simulation/standard/opendrive_schema">
<header revMajor="1" revMinor="6"/>
<road id="1" length="10" junction="-1"><link><successor elementType="road" elementId="2" contactPoint="start"/></link>
 <planView><geometry s="0" x="0" y="0" hdg="0" length="10"><line/></geometry></planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center>
  <right><lane id="-1" type="driving"><link><successor id="-1"/></link>
   <width sOffset="0" a="3" b="0" c="0" d="0"/></lane></right>
 </laneSection></lanes></road>
<road id="2" length="0.013" junction="-1">
 <link><predecessor elementType="road" elementId="1" contactPoint="end"/>
  <successor elementType="road" elementId="3" contactPoint="start"/></link>
 <planView><geometry s="0" x="10" y="0" hdg="0" length="0.013"><line/></geometry></planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center>
  <right><lane id="-1" type="driving"><link><predecessor id="-1"/><successor id="-1"/></link>
   <width sOffset="0" a="3" b="0" c="0" d="0"/></lane></right>
 </laneSection></lanes></road>
<road id="3" length="10" junction="-1"><link><predecessor elementType="road" elementId="2" contactPoint="end"/></link>
 <planView><geometry s="0" x="10.013" y="0" hdg="0" length="10"><line/></geometry></planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center>
  <right><lane id="-1" type="driving"><width sOffset="0" a="3" b="0" c="0" d="0"/></lane></right>
 </laneSection></lanes></road>
</OpenDRIVE>"""


def test_micro_road_shorter_than_the_step_is_kept_and_crossed():
    # Road 2 is 0.013 m long (like Town07's road 33): a 5 m step from road 1 crosses it into road 3.
    m = load_opendrive(_MICRO, name="Micro")
    start = m.get_waypoint_xodr(1, -1, 8.0)
    (ahead,) = start.next(5.0)
    # 2 m to the end of road 1, 0.013 m of road 2, the remaining 2.987 m on road 3.
    assert ahead.road_id == 3 and ahead.s == pytest.approx(2.987, abs=1e-9)
    assert ahead.transform.location.x == pytest.approx(13.0, abs=1e-9)
    (tiny,) = start.next(2.005)
    assert tiny.road_id == 2 and tiny.transform.location.x == pytest.approx(10.005, abs=1e-9)
    # Back 3.5 m: 2.987 m of road 3, 0.013 m of road 2, 0.5 m of road 1 → s = 9.5.
    assert [(w.road_id, round(w.s, 6)) for w in ahead.previous(3.5)] == [(1, 9.5)]
    assert m.name == "Micro"


def test_missing_file_and_bad_xml_name_the_source(tmp_path):
    missing = tmp_path / "nothere.xodr"
    with pytest.raises(OpenDriveError, match="nothere.xodr"):
        parse_opendrive(missing)
    broken = tmp_path / "broken.xodr"
    broken.write_text("<OpenDRIVE><road></OpenDRIVE>")
    with pytest.raises(OpenDriveError, match="broken.xodr.*well-formed"):
        parse_opendrive(broken)
    wrong_root = tmp_path / "root.xodr"
    wrong_root.write_text("<routes/>")
    with pytest.raises(OpenDriveError, match="root.xodr.*<routes>"):
        parse_opendrive(wrong_root)


def test_bad_attribute_names_element_and_line(tmp_path):
    bad = tmp_path / "bad.xodr"
    bad.write_text(_MICRO.replace('hdg="0" length="10"><line/>', 'hdg="east" length="10"><line/>', 1))
    with pytest.raises(OpenDriveError, match=r"bad.xodr: <geometry> \(line \d+\): attribute 'hdg'='east'"):
        parse_opendrive(bad)


def test_parsed_records_keep_ids_and_links():
    data = parse_opendrive(_MICRO)
    assert [r.id for r in data.roads] == [1, 2, 3] and data.rev_minor == 6
    road2 = data.road(2)
    assert road2.predecessor.element_id == 1 and road2.predecessor.contact_point == "end"
    assert road2.sections[0].lanes[-1].successor == -1 and road2.length == 0.013
