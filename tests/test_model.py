"""DGTNet: shapes, output range, torchvision-compatible names and weight loading, normalisation."""

import numpy as np
import pytest
import torch

from dgt_lib.core.config import VEHICLES
from dgt_lib.learning.model import (
    PATCH_SHAPE,
    ArchitectureMismatchError,
    DGTNet,
    PatchConv2d,
    ResNet18,
    centre_heights,
    live_taps,
)

WIDTH = 8  # small network: fast tests, same code path as the paper's width 64


@pytest.fixture
def model():
    torch.manual_seed(0)
    return DGTNet(width=WIDTH, fc_hidden=32).eval()


def test_output_is_batch_by_vehicles_in_unit_interval(model):
    x = torch.randn(5, 6, 22, 7) * 50  # far outside the normalised range
    y = model(x)
    assert y.shape == (5, len(VEHICLES))
    assert torch.all((y >= 0) & (y <= 1))


def test_heads_evaluate_a_shared_embedding(model):
    x = torch.randn(3, 6, 22, 7)
    z = model.embed(x)
    assert z.shape == (3, 32)
    torch.testing.assert_close(model.heads(z), model(x))


def test_single_task_model_has_one_head():
    m = DGTNet(vehicles=("vw_van",), width=WIDTH).eval()
    assert m(torch.zeros(2, 6, 22, 7)).shape == (2, 1)
    assert m.head_index("vw_van") == 0
    assert m.head_index(VEHICLES.index("vw_van")) == 0
    with pytest.raises(KeyError, match="no head for 'jeep'"):
        m.head_index("jeep")


@pytest.mark.parametrize("vehicles", [(), ("truck",), ("jeep", "jeep")])
def test_bad_vehicle_sets_are_rejected(vehicles):
    with pytest.raises(ValueError, match="vehicles"):
        DGTNet(vehicles=vehicles, width=WIDTH)


def test_wrong_input_shape_is_a_clear_error(model):
    with pytest.raises(ValueError, match=r"expected patches \(B, 6"):
        model(torch.zeros(2, 4, 22, 7))


def test_resnet_parameter_names_and_shapes_match_torchvision():
    state = ResNet18(3, 64).state_dict()
    assert len(state) == 120  # torchvision resnet18: 122 keys, minus fc.weight and fc.bias
    assert state["conv1.weight"].shape == (64, 3, 7, 7)
    assert state["layer1.0.conv1.weight"].shape == (64, 64, 3, 3)
    assert state["layer2.0.downsample.0.weight"].shape == (128, 64, 1, 1)
    assert state["layer3.0.downsample.1.running_var"].shape == (256,)
    assert state["layer4.1.conv2.weight"].shape == (512, 512, 3, 3)
    assert "layer1.0.downsample.0.weight" not in state  # torchvision: no downsample there


def _torchvision_like_file(tmp_path, width=64):
    """A state dict shaped like torchvision's resnet18 (incl. the fc classifier)."""
    torch.manual_seed(123)
    state = ResNet18(3, width).state_dict()
    state["fc.weight"] = torch.randn(1000, 8 * width)
    state["fc.bias"] = torch.randn(1000)
    path = tmp_path / "resnet18.pth"
    torch.save(state, path)
    return path, state


def test_imagenet_weights_load_into_the_rgb_branch_only(tmp_path):
    path, state = _torchvision_like_file(tmp_path)
    torch.manual_seed(0)
    m = DGTNet(rgb_weights=path)
    assert m.rgb_pretrained
    for k, v in m.rgb.state_dict().items():
        torch.testing.assert_close(v, state[k], rtol=0, atol=0)
    assert not torch.equal(m.height.conv1.weight, state["conv1.weight"])
    assert not DGTNet(width=WIDTH).rgb_pretrained


def test_imagenet_weights_of_another_shape_are_a_clear_error(tmp_path):
    path, _ = _torchvision_like_file(tmp_path, width=32)
    with pytest.raises(ArchitectureMismatchError, match="wrong shape"):
        DGTNet(rgb_weights=path)
    with pytest.raises(ArchitectureMismatchError, match="width=64"):
        DGTNet(width=WIDTH, rgb_weights=path)


def test_normalisation_is_applied_inside_forward_and_saved(model):
    # H̄ is centred on each patch before normalising, so its mean statistic is ~0
    mean = np.array([0.4, 0.5, 0.3, 0.0, 0.1, 0.2], dtype=np.float32)
    std = np.array([0.2, 0.2, 0.1, 3.0, 0.05, 0.1], dtype=np.float32)
    x = torch.randn(4, 6, 22, 7) * torch.from_numpy(std)[:, None, None] \
        + torch.from_numpy(mean)[:, None, None]
    expected = model((centre_heights(x) - torch.from_numpy(mean)[:, None, None])
                     / torch.from_numpy(std)[:, None, None])
    model.set_normalization(mean, std)
    torch.testing.assert_close(model(x), expected)
    state = model.state_dict()
    np.testing.assert_array_equal(state["input_mean"].numpy(), mean)
    np.testing.assert_array_equal(state["input_std"].numpy(), std)


def test_normalisation_rejects_zero_std(model):
    with pytest.raises(ValueError, match="std > 0"):
        model.set_normalization(np.zeros(6), np.zeros(6))


def test_unobserved_nan_cells_give_finite_predictions(model):
    x = torch.randn(2, 6, 22, 7)
    x[:, :, :5] = float("nan")
    assert torch.isfinite(model(x)).all()


def test_heights_are_relative_to_the_patch_so_altitude_does_not_matter():
    """The same terrain 12 m higher (a summit plateau) gives the same prediction."""
    import torch


    torch.manual_seed(0)
    model = DGTNet(width=8, fc_hidden=16).eval()
    x = torch.rand(4, 6, 22, 7)
    higher = x.clone()
    higher[:, 3] += 12.0
    with torch.no_grad():
        torch.testing.assert_close(model(x), model(higher), atol=1e-5, rtol=0)
    centred = centre_heights(x.numpy())
    np.testing.assert_allclose(centred[:, 3].mean(axis=(1, 2)), 0.0, atol=1e-5)
    np.testing.assert_array_equal(centred[:, :3], x.numpy()[:, :3])


@pytest.mark.parametrize("n, k, p, s, expected", [
    (1, 3, 1, 1, (1, 2, 0, 0)),  # a 1×1 map: only the centre tap meets it
    (2, 3, 1, 2, (1, 3, 0, 0)),  # 2 → 1 with stride 2: the centre and the tap after it
    (7, 7, 3, 2, (0, 7, 3, 3)),  # the stem across a patch: every tap is live
    (3, 3, 1, 1, (0, 3, 1, 1)),
])
def test_live_taps_are_the_kernel_taps_that_meet_the_input(n, k, p, s, expected):
    assert live_taps(n, k, p, s) == expected


def test_live_taps_compute_the_same_network_with_the_same_parameters():
    torch.manual_seed(1)
    full, live = DGTNet(width=8, fc_hidden=16), DGTNet(width=8, fc_hidden=16)
    live.load_state_dict(full.state_dict())
    live.use_live_taps()
    assert list(live.state_dict()) == list(full.state_dict())  # checkpoints interchange
    x = torch.rand(32, *PATCH_SHAPE)
    x[0, :, 5, 3] = float("nan")  # an unobserved cell
    for net in (full, live):  # training mode: BatchNorm on the batch, as in a training step
        net.train()
        net(x).square().sum().backward()
    torch.testing.assert_close(live(x), full(x), rtol=1e-5, atol=1e-6)
    for (name, a), b in zip(full.named_parameters(), live.parameters(), strict=True):
        scale = a.grad.abs().max()  # gradients equal up to rounding, at each tensor's scale
        assert (b.grad - a.grad).abs().max() <= 1e-5 * scale + 1e-12, name
    # on 1×1 maps every tap but the centre multiplies padding: its gradient is zero
    dead = torch.ones(3, 3)
    dead[1, 1] = 0
    for net in (full, live):
        grad = net.rgb.layer4[1].conv2.weight.grad
        assert grad[:, :, 1, 1].abs().sum() > 0 and (grad * dead).abs().sum() == 0
    live.use_live_taps(False)
    assert not any(m.live_taps for m in live.modules() if isinstance(m, PatchConv2d))
