"""The small-collection recipe's GC edits (diffusion.augment): every setting comes from conf
(the recipe gives them all), and one left out is named."""
import numpy as np
import pytest

from ngc_gen.app.runtime.config import compose_config
from ngc_gen.app.stages.train_diffusion import AUGMENT_KEYS, augmented_latents
from ngc_gen.data.errors import DataError


def test_the_collection_recipe_gives_every_augment_key():
    cfg = compose_config("train", ["experiment=collection", "data.path=.", "run_dir=.",
                                   "annotate.template=datasets/animals/quadruped_transfer.yaml"])
    diffusion = [o for o in cfg.pipeline.diffusion if o.startswith("diffusion.augment=")]
    assert len(diffusion) == 1 and all(f"{k}:" in diffusion[0] for k in AUGMENT_KEYS
                                       if k != "template") and "template:" in diffusion[0]


def test_an_augment_without_a_key_names_it():
    with pytest.raises(DataError, match=r"diffusion.augment has no \['swing_min_length'") as e:
        augmented_latents(None, {k: 1 for k in AUGMENT_KEYS if k != "swing_min_length"})
    assert "collection.yaml" in str(e.value)
