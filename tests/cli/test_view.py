"""b2d-view montage modes through ``main(argv)``."""

from __future__ import annotations

import cv2
import numpy as np

from b2d_data.cli import view as view_cli
from b2d_data.format.names import ClipName
from b2d_data.loaders.synthetic import SyntheticClipSpec, write_synthetic_clip


def test_clip_frame_montage(tmp_path, capsys):
    clip = write_synthetic_clip(tmp_path, SyntheticClipSpec(ClipName.parse("Accident_Town03_Route1_Weather0"),
                                                            frames=2, dense=False, lidar_points=50, radar=False,
                                                            expert=False))  # fmt: skip
    out = tmp_path / "m.png"
    assert view_cli.main(["--clip", str(clip), "--frame", "1", "--out", str(out)]) == 0
    image = cv2.imread(str(out))
    # Layout of make_montage: 3 tiles of 640 px per row; two camera rows and a bottom row 1.5 tiles high.
    assert image.shape[1] == 1920 and image.shape[0] > 0
    assert image.std() > 5.0  # something was drawn, not a blank canvas
    assert "montage" in capsys.readouterr().out


def test_town_montage_and_errors(tmp_path, capsys):
    out = tmp_path / "town.png"
    assert view_cli.main(["--town", "interurban", "--size", "96x54", "--out", str(out)]) == 0
    image = cv2.imread(str(out))
    assert image.shape[1] == 1920 and np.unique(image.reshape(-1, 3), axis=0).shape[0] > 50
    assert view_cli.main(["--town", "Nowhere", "--out", str(out)]) == 1
    assert "unknown town 'Nowhere'" in capsys.readouterr().err
    assert view_cli.main(["--clip", str(tmp_path / "missing"), "--out", str(out)]) == 1
