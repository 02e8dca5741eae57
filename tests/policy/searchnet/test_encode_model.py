import numpy as np
import pytest
import torch

from policy.searchnet import SearchNet, SearchNetConfig
from policy.searchnet.encode import OFFSET_SCALE, action_mask, egocentric, egocentric_np


def test_egocentric_matches_a_cell_by_cell_recentring() -> None:
    rng = np.random.default_rng(0)
    b, c, h, w = 4, 3, 5, 7
    planes = rng.random((b, c, h, w)).astype(np.float32)
    pos = np.stack([rng.integers(0, w, b), rng.integers(0, h, b)], axis=1)
    x = egocentric(torch.from_numpy(planes), torch.from_numpy(pos)).numpy()
    assert x.shape == (b, c + 3, 2 * h - 1, 2 * w - 1)
    for k in range(b):
        for i in range(2 * h - 1):
            for j in range(2 * w - 1):
                yy, xx = pos[k, 1] + i - (h - 1), pos[k, 0] + j - (w - 1)
                inside = 0 <= yy < h and 0 <= xx < w
                want = planes[k, :, yy, xx] if inside else np.zeros(c)
                np.testing.assert_array_equal(x[k, :c, i, j], want)
                assert x[k, c, i, j] == float(inside)
                assert x[k, c + 1, i, j] == pytest.approx((j - (w - 1)) / OFFSET_SCALE)
                assert x[k, c + 2, i, j] == pytest.approx((i - (h - 1)) / OFFSET_SCALE)
    np.testing.assert_array_equal(egocentric_np(planes, pos), x)  # the decision path's numpy twin
    for k in range(b):
        np.testing.assert_array_equal(egocentric_np(planes[k: k + 1], pos[k: k + 1]), x[k: k + 1])


@pytest.mark.parametrize("size", [(10, 10), (20, 20), (6, 9)])
def test_one_network_decides_on_any_field_size_and_never_picks_a_masked_move(size: tuple[int, int]) -> None:
    h, w = size
    torch.manual_seed(0)
    net = SearchNet(SearchNetConfig(in_channels=4)).eval()
    planes = torch.rand(8, 4, h, w)
    pos = torch.stack([torch.randint(0, w, (8,)), torch.randint(0, h, (8,))], dim=1)
    valid = torch.rand(8, 4) > 0.3
    valid[:, 0] = True
    mask = action_mask(valid, 5)
    assert not mask[:, 4].any()  # static worlds: no stay
    logits = net(egocentric(planes, pos), mask)
    assert logits.shape == (8, 5)
    assert mask[torch.arange(8), logits.argmax(1)].all()


def test_config_rejects_bad_values_by_name() -> None:
    with pytest.raises(ValueError, match="local"):
        SearchNetConfig(in_channels=4, local=4)
    with pytest.raises(ValueError, match="in_channels"):
        SearchNetConfig(in_channels=0)
