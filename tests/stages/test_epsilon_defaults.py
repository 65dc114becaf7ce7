"""The stage ``epsilon`` defaults to the Stream Line preset (issue 16: a notebook call).

``estimate_epsilon(sf)`` must do what ``cwproc retrieve -c streamline`` does: the
pipeline passes ``probe=probe_for(config)``, ``lag_number=config.turbulence.lag_number``
and ``model=config.turbulence.model`` (``pipeline.process_scans``), so those defaults
must equal the preset's values, and no other default may shadow a setting of the
``[turbulence]`` table.
"""

from __future__ import annotations

import dataclasses
import inspect

from cwproc.config import load_config
from cwproc.pipeline import probe_for
from cwproc.stages.epsilon import estimate_epsilon


def _defaults() -> dict[str, object]:
    return {
        name: p.default
        for name, p in inspect.signature(estimate_epsilon).parameters.items()
        if p.default is not inspect.Parameter.empty
    }


def test_defaults_equal_the_streamline_preset():
    config = load_config("streamline")
    expected = {
        "probe": probe_for(config),
        "lag_number": config.turbulence.lag_number,
        "model": config.turbulence.model,
    }
    defaults = _defaults()
    for name, value in expected.items():
        assert defaults[name] == value, name
    # the preset's probe is the pulsed Stream Line gate of Smalikho (2020), eq. 19
    assert (defaults["probe"].delta_p_m, defaults["probe"].delta_r_m) == (15.3, 18.0)


def test_no_other_default_shadows_a_turbulence_setting():
    fields = {f.name for f in dataclasses.fields(load_config("streamline").turbulence)}
    others = set(_defaults()) - {"probe", "lag_number", "model"}
    assert others, "the stage has estimator settings beyond the configuration's"
    assert not others & fields
