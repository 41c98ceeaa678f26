"""RecognizerConfig -> DatasetConfig: the training-grasp source is part of the config (and cache key)."""

from haptic_env.cache import config_key
from haptic_env.dataset import DatasetConfig
from haptic_env.recognizers.recognizer import RecognizerConfig


def test_geometric_source_reaches_the_dataset_config():
    surf = RecognizerConfig()
    geo = RecognizerConfig(grasps=DatasetConfig(source="geometric"))
    d = geo.dataset_config(3, True, hand_fingers=4)
    assert (d.source, d.hand_fingers, d.n_fingers, d.support) == ("geometric", 4, 3, "table")
    assert surf.dataset_config(3, True, hand_fingers=4).hand_fingers is None  # surface: no hand
    assert config_key(surf) != config_key(geo)
    five = RecognizerConfig(grasps=DatasetConfig(source="geometric", hand_fingers=5))
    assert five.dataset_config(3, True, 4).hand_fingers == 5
