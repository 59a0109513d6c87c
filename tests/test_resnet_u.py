"""ResNet-U: outputs and their ranges, checkpoints, training on the small real manifest."""

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from export import ResNetU, ResNetUConfig, load_checkpoint, save_checkpoint  # noqa: E402
from export.model.backbones import load_imagenet_weights  # noqa: E402
from export.train.dataset import read_manifest  # noqa: E402
from export.train.trainer import TrainOptions, train  # noqa: E402
from posecam.errors import InputError, ModelError  # noqa: E402
from posecam.skeleton import H36M_JOINTS  # noqa: E402

DATA = Path(__file__).parent / "data"
MANIFEST = DATA / "train_small" / "manifest.jsonl"
SMALL = ResNetUConfig(backbone="mobilenetv2", input_size=128, head_channels=64)


def test_default_is_the_papers_resnet_u():
    m = ResNetU()
    c = m.config
    assert (c.backbone, c.input_size, c.joints) == ("resnet50", 256, H36M_JOINTS)
    assert m.backbone.channels == (512, 1024)           # layer2, layer3 (block 4f)
    assert m.root_depth[0].in_features == 1024 + 4      # global features ++ box
    assert m.root_depth[0].out_features == 256
    assert not any(isinstance(x, torch.nn.BatchNorm1d) for x in m.modules())


def test_outputs_shapes_and_ranges():
    torch.manual_seed(0)
    m = ResNetU(SMALL).eval()
    with torch.no_grad():
        uv, depth, z, conf = m(torch.randn(3, 3, 128, 128) * 3, torch.rand(3, 4))
    assert uv.shape == (3, 17, 2) and depth.shape == (3, 17) and z.shape == (3, 1) and conf.shape == (3, 17)
    assert ((uv >= -0.5) & (uv <= 127.5)).all()
    assert (depth.abs() <= 1000).all()
    assert ((z > 0) & (z < 10_000)).all()
    assert ((conf >= 0) & (conf <= 1)).all()


def test_trains_with_batch_one():
    """A batch of one trains (no BatchNorm1d in the head) and every trainable weight gets a
    finite gradient, the z_a head and the first backbone convolution included."""
    m = ResNetU(SMALL).train()
    out = m(torch.randn(1, 3, 128, 128), torch.rand(1, 4))
    sum(o.sum() for o in out).backward()
    missing = [n for n, p in m.named_parameters() if p.requires_grad and p.grad is None]
    assert not missing, f"no gradient reached {missing[:5]}"
    grads = [p.grad for p in m.parameters() if p.requires_grad]
    assert all(torch.isfinite(g).all() for g in grads)
    assert sum(float(g.abs().sum()) for g in grads) > 0


def test_light_backbones_and_imagenet_weights():
    for name in ("resnet18", "resnet34"):
        assert ResNetU(ResNetUConfig(backbone=name, input_size=128, head_channels=64)).backbone.channels == (128, 256)
    m = ResNetU(SMALL)
    load_imagenet_weights(m.backbone, "mobilenetv2")
    with pytest.raises(InputError):
        load_imagenet_weights(ResNetU(ResNetUConfig(backbone="resnet18")).backbone, "resnet18")
    with pytest.raises(InputError):
        ResNetUConfig(backbone="vgg16")
    with pytest.raises(InputError):
        ResNetUConfig(input_size=100)


def test_checkpoint_round_trip(tmp_path):
    torch.manual_seed(1)
    m = ResNetU(ResNetUConfig(backbone="resnet18", input_size=128, head_channels=64, train_focal=1500.0,
                              train_image_width=1920.0)).eval()
    save_checkpoint(m, tmp_path / "ck.pt", {"step": 3})
    back = load_checkpoint(tmp_path / "ck.pt")
    assert back.config == m.config
    x, box = torch.randn(2, 3, 128, 128), torch.rand(2, 4)
    with torch.no_grad():
        for a, b in zip(m(x, box), back(x, box)):
            assert torch.equal(a, b)


def test_non_checkpoints_are_refused(tmp_path):
    with pytest.raises(ModelError, match="not a posecam ResNet-U checkpoint"):
        load_checkpoint(DATA / "messi5.jpg")
    torch.save({"weights": torch.zeros(3)}, tmp_path / "other.pt")
    with pytest.raises(ModelError, match="no format"):
        load_checkpoint(tmp_path / "other.pt")
    torch.save({"obj": Path("x")}, tmp_path / "pickled.pt")          # weights_only refuses objects
    with pytest.raises(ModelError, match="weights_only"):
        load_checkpoint(tmp_path / "pickled.pt")
    with pytest.raises(InputError, match="does not exist"):
        load_checkpoint(tmp_path / "missing.pt")


def test_manifest_errors_name_the_line(tmp_path):
    good = MANIFEST.read_text().splitlines()[0]
    bad = json.loads(good)
    bad["joints"] = bad["joints"][:5]
    (tmp_path / "m.jsonl").write_text(good.replace('"image": "', '"image": "' + str(MANIFEST.parent) + "/")
                                      + "\n" + json.dumps(bad) + "\n")
    with pytest.raises(InputError, match=r"m.jsonl:2:"):
        read_manifest(tmp_path / "m.jsonl")


@pytest.mark.slow
def test_training_loss_falls(tmp_path):
    torch.set_num_threads(2)
    opts = TrainOptions(MANIFEST, tmp_path / "ck.pt", backbone="mobilenetv2", input_size=128, head_channels=64,
                        steps=14, batch=4, pretrained=True, save_every=0)
    result = train(opts, show_progress=False)
    losses = np.array(result.losses)
    assert result.steps == 14 and not result.interrupted
    assert losses[-4:].mean() < 0.85 * losses[:4].mean()
    m = load_checkpoint(tmp_path / "ck.pt")
    assert 270 <= m.config.train_image_width <= 272             # the fixture's frames, downscaled 4x
    assert 400 < m.config.train_focal < 440


@pytest.mark.parametrize("changes, words", [
    ({"input_size": 100_000}, "input size"), ({"input_size": 0}, "input size"),
    ({"head_channels": -4}, "head_channels"), ({"head_channels": 1 << 20}, "head_channels"),
    ({"u_blocks": 0}, "u_blocks"), ({"u_blocks": 1000}, "u_blocks"),
    ({"joints": ()}, "joints"), ({"train_focal": float("inf")}, "train_focal"),
])
def test_configs_that_ask_for_absurd_sizes_are_refused(changes, words):
    """A checkpoint's config is untrusted: sizes that would exhaust memory are refused up front."""
    with pytest.raises(InputError, match=words):
        ResNetUConfig.from_dict({**SMALL.to_dict(), **changes})
