"""The host torture test's second host (issue 16): the VST3 in DawDreamer (JUCE's plugin
hosting, from PyPI), beside pedalboard's run in host_test.py.

DawDreamer automates parameters sample-accurately, so here every parameter the host can change
without a re-solve gets a new random value at every block boundary, at every sample rate from
22.05 to 192 kHz and block sizes from 1 to 4096, while 2000 notes a second arrive. The output
must stay finite and bounded. Then a project state saved mid-note at 48 kHz is loaded into a
fresh instance at 96 kHz: every parameter comes back bit-exact, and it plays.

Usage: python dawdreamer_torture.py path/to/ModalForge.vst3
"""

import os
import sys
import tempfile

import dawdreamer as daw
import numpy as np

# Each change of these re-solves the object (hex27 at 200 modes takes seconds): the host test
# sets them in pedalboard, and the worker's coalescing is tested in the engine.
SOLVE_PARAMS = {"Solver", "Answers", "Element", "Modes"}
# 16 voices at +24 dB of a normalised strike (0.5 peak each) stay below 130; anything near
# this bound is a runaway.
BOUND = 1000.0
RATES = (22050, 44100, 48000, 96000, 192000)
BLOCKS = (1, 16, 64, 333, 4096)
NOTES_PER_S = 2000


def fuzzable(proc):
    return [
        d for d in proc.get_parameters_description()
        if not d["name"].startswith("MIDI Ch.") and d["name"] not in SOLVE_PARAMS
    ]


def torture_case(vst3, rate, block, rng):
    engine = daw.RenderEngine(rate, block)
    synth = engine.make_plugin_processor("modalforge", vst3)
    seconds = max(0.1, 8 * block / rate)
    samples = int(round(seconds * rate))
    blocks = -(-samples // block)
    params = fuzzable(synth)
    for d in params:
        # A new value at every block boundary (DawDreamer reads automation per block).
        per_block = rng.random(blocks).astype(np.float32)
        synth.set_automation(d["index"], np.repeat(per_block, block)[:samples])
    for i in range(int(NOTES_PER_S * seconds)):
        synth.add_midi_note(int(rng.integers(24, 108)), int(rng.integers(1, 128)),
                            i / NOTES_PER_S, 0.01)
    engine.load_graph([(synth, [])])
    engine.render(seconds)
    x = engine.get_audio()
    assert x.shape[1] >= samples - block, (rate, block, x.shape)
    assert np.isfinite(x).all(), f"NaN or inf at {rate} Hz, block {block}"
    peak = float(np.abs(x).max())
    assert peak < BOUND, f"output {peak} at {rate} Hz, block {block}"
    return len(params), peak


def restored(vst3, path, rate, block, indices):
    """A fresh instance at `rate` with the state at `path` loaded, after playing a note: its
    parameter values, and the engine and instance (the processor dies with its engine, and
    DawDreamer then crashes on it: keep both)."""
    engine = daw.RenderEngine(rate, block)
    synth = engine.make_plugin_processor("restored", vst3)
    synth.load_state(path)
    synth.add_midi_note(67, 90, 0.0, 0.5)
    engine.load_graph([(synth, [])])
    engine.render(0.2)
    y = engine.get_audio()
    assert np.isfinite(y).all() and 0 < np.abs(y).max() < BOUND, np.abs(y).max()
    return {i: synth.get_parameter(i) for i in indices}, (engine, synth)


def state_across_rates(vst3, rng):
    """Random parameters, a note, the state saved mid-note at 48 kHz; loaded at 96 kHz and
    at 22.05 kHz (saved again from the 96 kHz instance): the two restores agree bit-exact,
    and each value is the one set, up to the parameter's own step (the plugin quantises
    discrete parameters; the host's copy right after setting is its unquantised value)."""
    engine = daw.RenderEngine(48000, 256)
    synth = engine.make_plugin_processor("a", vst3)
    descriptions = [d for d in synth.get_parameters_description()
                    if not d["name"].startswith("MIDI Ch.")]
    for d in descriptions:
        if d["name"] not in SOLVE_PARAMS:
            synth.set_parameter(d["index"], float(rng.random()))
        # The damping law from the material (its knobs keep their random values, saved and
        # restored like the rest): random knobs of the power law can overdamp every mode
        # (decay above the angular frequency: no oscillation, rightly silent; mu1 5.6 and
        # mu2 0.59 put G4's decay at 56,000 /s), and a silent instance cannot show it plays.
        if d["name"] == "Damping":
            synth.set_parameter(d["index"], 0.0)
    synth.add_midi_note(60, 100, 0.0, 1.0)
    engine.load_graph([(synth, [])])
    engine.render(0.05)
    indices = [d["index"] for d in descriptions]
    set_values = {i: synth.get_parameter(i) for i in indices}
    set_texts = {i: synth.get_parameter_text(i) for i in indices}
    with tempfile.TemporaryDirectory() as tmp:
        first_path = os.path.join(tmp, "first")
        synth.save_state(first_path)
        first, instance = restored(vst3, first_path, 96000, 333, indices)
        second_path = os.path.join(tmp, "second")
        instance[1].save_state(second_path)
        second, _ = restored(vst3, second_path, 22050, 64, indices)
    diff = {i: (first[i], second[i]) for i in indices if first[i] != second[i]}
    assert not diff, f"parameters not restored bit-exact: {diff}"
    for d in descriptions:
        i = d["index"]
        step = 1.0 / d["numSteps"] if d["isDiscrete"] or d["isBoolean"] else 1e-5
        # The state keeps plain values as f32: at the bottom of a skewed range (normalised
        # n -> min + range * n^4) a small n is below f32's resolution of the plain value
        # (n = 0.0014 on the 10-2000 Hz low cut is 10.000000008 Hz, stored as 10 Hz, n = 0).
        # There the value must read the same as the plugin displays it.
        same = abs(first[i] - set_values[i]) <= step
        assert same or instance[1].get_parameter_text(i) == set_texts[i], (
            d["name"], set_values[i], first[i], set_texts[i])
    return len(indices)


def side_chain(vst3, rng):
    """The resonator effect through a real host's side-chain (issue 15): DawDreamer routes a
    playback processor into the plugin's input bus, no notes are played. Full-scale noise
    comes out resonated: audible (it excites every mode), finite and bounded; a sine at
    1 kHz, between the default bowl's modes, finite, bounded and quieter. The engine tests
    hold the exact responses and the NaN, infinity and denormal inputs a host cannot send."""
    rate, block = 48000, 256
    results = []
    for name, signal in [
        ("noise", rng.uniform(-1.0, 1.0, (2, rate * 2)).astype(np.float32)),
        ("sine", np.tile(np.sin(2 * np.pi * 1000.0 * np.arange(rate * 2) / rate),
                         (2, 1)).astype(np.float32)),
    ]:
        engine = daw.RenderEngine(rate, block)
        source = engine.make_playback_processor("source", signal)
        synth = engine.make_plugin_processor("modalforge", vst3)
        engine.load_graph([(source, []), (synth, ["source"])])
        engine.render(2.0)
        x = engine.get_audio()
        assert np.isfinite(x).all(), f"{name}: NaN or inf"
        level = float(np.sqrt(np.mean(x[:, rate:] ** 2)))
        peak = float(np.abs(x).max())
        assert peak < BOUND, f"{name}: peak {peak}"
        if name == "noise":
            assert level > 1e-3, f"noise: rms {level}: the side-chain is not heard"
        results.append(f"{name} rms {level:.3g} peak {peak:.3g}")
    return results


def main():
    vst3 = sys.argv[1]
    rng = np.random.default_rng(1616)
    worst = 0.0
    cases = 0
    fuzzed = 0
    for rate in RATES:
        for block in BLOCKS:
            fuzzed, peak = torture_case(vst3, rate, block, rng)
            worst = max(worst, peak)
            cases += 1
    restored = state_across_rates(vst3, rng)
    resonated = side_chain(vst3, rng)
    print(f"dawdreamer side-chain through the resonator effect: {'; '.join(resonated)}")
    print(f"dawdreamer torture: {cases} cases ({len(RATES)} rates x {len(BLOCKS)} blocks), "
          f"{fuzzed} parameters automated to new random values every block, "
          f"{NOTES_PER_S} notes/s, peak {worst:.3g}; {restored} parameters restored bit-exact "
          f"from 48 to 96 kHz")


if __name__ == "__main__":
    main()
