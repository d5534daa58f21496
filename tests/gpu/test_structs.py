"""Structs declared once in Python (pycinder.gpu.structs): their layout follows WGSL's alignment
rules, the host writes them by name, and a shader reads what the host wrote, field by field,
including a field added to a real pass's parameters."""

import re
from pathlib import Path

import numpy as np
import pytest
import wgpu

import pycinder
from pycinder.gpu.structs import Field, Struct, declarations
from pycinder.gpu.bindings import Stage
from pycinder.focused.frame.frames import PASSES

SHADERS = Path(pycinder.__file__).parent / "shaders"


def test_layout_follows_wgsl_alignment_rules():
    """Offsets and sizes from the WGSL spec's "Alignment and Size" table, worked by hand."""
    s = Struct("S", [("a", "u32"), ("b", "vec3f"), ("c", "f32"), ("d", "vec2u"),
                     ("e", "mat4x4f"), ("f", "array<vec4f, 3>"), ("g", "i32")])
    assert [s.offset(n) for n in "abcdefg"] == [0, 16, 28, 32, 48, 112, 160]
    assert (s.align, s.size) == (16, 176)
    assert s.dtype.itemsize == 176
    packed = Struct("P", [("x", "array<u32, 3>"), ("y", "array<u32, 4>"), ("z", "u32")])
    assert [packed.offset(n) for n in "xyz"] == [0, 12, 28] and packed.size == 32


@pytest.mark.parametrize("fields, message", [
    ([("a", "array<u32, 4>")], "16"),                   # uniform arrays need a 16-byte stride
    ([("a", "array<vec3f, 2>")], "pads each element"),  # host and WGSL would disagree
    ([("a", "mat3x3f")], "padded columns"),
    ([("a", "bool")], "unsupported"),
    ([("a", "u32"), ("a", "f32")], "twice"),
])
def test_layouts_the_host_cannot_mirror_are_refused(fields, message):
    with pytest.raises(ValueError, match=message):
        Struct("Bad", fields, uniform=True)


def test_blocks_at_a_stride_keep_field_offsets():
    s = Struct("B", [("n", "u32"), ("scale", "f32"), ("origin", "vec4f")])
    blocks = s.zeros(3, stride=256)
    blocks["n"] = [1, 2, 3]
    blocks["origin"][2] = (1, 2, 3, 4)
    raw = blocks.view(np.uint8).reshape(3, 256)
    assert raw[1, :4].view(np.uint32)[0] == 2
    assert raw[2, 16:32].view(np.float32).tolist() == [1, 2, 3, 4]
    with pytest.raises(ValueError, match="does not fit"):
        s.zeros(2, stride=24)


def _echo(gpu, struct: Struct, values: np.ndarray) -> np.ndarray:
    """Bind ``values`` (one ``struct``) as a uniform, and have a shader copy each field it reads
    into a storage buffer, as u32 words (f32 bitcast), in declaration order."""
    lines, count = [], 0
    for f in struct.fields:
        n = int(np.prod(struct.dtype.fields[f.name][0].shape or (1,)))
        if f.wgsl in ("u32", "f32", "i32"):
            lines.append(f"out[{count}u] = bitcast<u32>(params.{f.name});")
        else:
            flat = [f"params.{f.name}[{i}]" for i in range(n)] if f.wgsl.startswith("vec") else \
                [f"params.{f.name}[{i // 4}][{i % 4}]" for i in range(n)]
            lines += [f"out[{count + i}u] = bitcast<u32>({x});" for i, x in enumerate(flat)]
        count += n
    source = (declarations([struct]) +
              "@group(0) @binding(0) var<uniform> params: Echo;\n"
              "@group(0) @binding(1) var<storage, read_write> out: array<u32>;\n"
              "@compute @workgroup_size(1) fn main() {\n    " + "\n    ".join(lines) + "\n}\n")
    device = gpu.device
    module = device.create_shader_module(code=source)
    pipeline = device.create_compute_pipeline(layout="auto",
                                              compute={"module": module, "entry_point": "main"})
    uniform = device.create_buffer_with_data(data=values.tobytes() + bytes(16),
                                             usage=wgpu.BufferUsage.UNIFORM)
    out = device.create_buffer(size=4 * count, usage=wgpu.BufferUsage.STORAGE |
                               wgpu.BufferUsage.COPY_SRC)
    group = device.create_bind_group(layout=pipeline.get_bind_group_layout(0), entries=[
        {"binding": 0, "resource": {"buffer": uniform}},
        {"binding": 1, "resource": {"buffer": out}}])
    encoder = device.create_command_encoder()
    cpass = encoder.begin_compute_pass()
    cpass.set_pipeline(pipeline)
    cpass.set_bind_group(0, group)
    cpass.dispatch_workgroups(1)
    cpass.end()
    device.queue.submit([encoder.finish()])
    return np.frombuffer(device.queue.read_buffer(out), dtype=np.uint32)


def _expected(struct: Struct, values: np.ndarray) -> np.ndarray:
    return np.concatenate([np.ascontiguousarray(values[f.name]).reshape(-1).view(np.uint32)
                           for f in struct.fields])


def test_a_field_added_to_a_pass_parameters_struct_is_seen_by_both_sides():
    """The cull's parameters with a field added in the middle (shifting every later offset), a
    float and a vector among them: the host writes them by name, and the shader generated from
    the same declaration reads each one back."""
    from pycinder.focused.frame.f1_cull import PARAMS

    fields = list(PARAMS.fields)
    fields[3:3] = [Field("added", "f32", "a new field"), Field("extra", "vec4u", "")]
    struct = Struct("Echo", fields, uniform=True)
    assert struct.offset("face_cap") > PARAMS.offset("face_cap")
    values = struct.zeros()
    for k, f in enumerate(struct.fields):
        values[f.name] = np.arange(k * 7 + 1, k * 7 + 1 + values[f.name].size).reshape(
            values[f.name].shape)
    values["added"] = 0.375
    got = _echo(pycinder.Detector().gpu, struct, values)
    assert got.tolist() == _expected(struct, values).tolist()


def test_every_pass_parameters_struct_round_trips_through_a_shader():
    gpu = pycinder.Detector().gpu
    for cls in PASSES:
        params = getattr(cls, "PARAMS", None)
        if params is None:
            continue
        struct = Struct("Echo", params.fields, uniform=True)
        values = struct.zeros()
        for k, f in enumerate(struct.fields):
            values[f.name] = k + 11
        assert _echo(gpu, struct, values).tolist() == _expected(struct, values).tolist(), \
            cls.__name__


def test_no_shader_declares_a_struct_the_host_writes():
    """Every struct the host writes is generated: no .wgsl file declares one by hand."""
    host = {s.name for s in _host_structs()}
    declared = {m for path in SHADERS.glob("*.wgsl")
                for m in re.findall(r"^struct (\w+)", path.read_text(), flags=re.M)}
    assert not host & declared, host & declared


def _host_structs() -> list[Struct]:
    """Every Struct declared at module level in pycinder (the layout, the passes of every
    strategy, the broad phase, the buffers)."""
    import importlib
    import pkgutil

    out = []
    for info in pkgutil.walk_packages(pycinder.__path__, "pycinder."):
        if info.name.startswith(("pycinder.demos", "pycinder.batch")):
            continue
        module = importlib.import_module(info.name)
        out += [v for v in vars(module).values() if isinstance(v, Struct)]
    assert len(out) > 10
    return out


def test_stage_binds_generated_structs_by_name():
    """A stage whose shader uses a pass's struct compiles only with the struct given."""
    from pycinder.focused.frame.f0_bounds import PARAMS

    gpu = pycinder.Detector().gpu
    stage = Stage(gpu, "frame_bounds", "cluster_bounds", structs=(PARAMS,))
    assert stage.numbers["params"] == 5
