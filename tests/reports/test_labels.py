"""Names of method variants and surface configurations."""

import numpy as np
import pandas as pd

from parambench.reports.labels import add_labels, config_label, variant_labels


def test_variant_label_names_only_the_parameters_that_vary():
    rows = pd.DataFrame({
        "method": ["ocp", "ocp", "ocp", "lscm", "sdp"],
        "params": ['{"k": 8, "eps": 0.001, "seed": 0}', '{"k": 12, "eps": 0.001, "seed": 1}',
                   '{"k": 8, "eps": 0.001, "seed": 2}', "{}", '{"k": 10}'],
    })
    assert list(variant_labels(rows)) == ["ocp [k=8]", "ocp [k=12]", "ocp [k=8]", "lscm", "sdp"]


def test_variant_label_with_two_varying_parameters_and_a_missing_one():
    rows = pd.DataFrame({"method": ["m", "m", "m"],
                         "params": ['{"a": 1, "b": 0.5}', '{"a": 2, "b": 0.5}', '{"a": 2}']})
    assert list(variant_labels(rows)) == ["m [a=1, b=0.5]", "m [a=2, b=0.5]", "m [a=2]"]


def test_config_label_leaves_out_what_does_not_apply():
    assert config_label("bump", 2000.0, "poisson", 0.0) == "bump · 2000 pts · poisson"
    assert config_label("bump", 2000.0, "poisson", 0.1) == "bump · 2000 pts · poisson · noise 0.1"
    assert config_label("real/bunny", 0.0, "", 0.0) == "real/bunny"
    assert config_label("real/bunny", np.nan, "", np.nan) == "real/bunny"


def test_add_labels_groups_real_datasets_with_missing_size():
    rows = pd.DataFrame({"dataset": ["real/bunny", "real/bunny"], "size": [np.nan, 0.0],
                         "sampling": ["", ""], "noise": [np.nan, 0.0], "method": ["a", "a"],
                         "params": ["{}", "{}"]})
    out = add_labels(rows)
    assert out["config"].nunique() == 1
    assert list(out["size"]) == [0.0, 0.0]
