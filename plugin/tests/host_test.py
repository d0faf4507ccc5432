"""The plugin in a real third-party host (Spotify's pedalboard, a JUCE VST3 host).

Loads target/bundled/ModalForge.vst3, sends MIDI notes, renders audio, and checks:
1. the strongest spectral peaks are modes that `modalforge modes` computes for the same object
   (the default 16-voxel glass bowl, 0.2 m) within 1% (FFT resolution here is ~0.1 Hz; the
   engine plays the same FEM modes, so any mismatch beyond that is a wrong object, material or
   scaling);
2. parameters set from the host change the sound: material glass -> steel (a re-solve: the
   Poisson's ratio differs) and size 0.2 -> 0.1 m (a voicing change: every mode doubles); the
   peaks follow `modalforge modes` for the new settings within 1% and leave the old ones.
   (Lightly damped materials: a heavily damped one, like wood, has Lorentzian peaks hundreds
   of Hz wide whose overlap moves the spectral maxima by more than the modes' spacing.)
3. "pitch" mapping puts the fundamental on the played note (A4 = 440 Hz, within 1%), and the
   default glass bowl on C4 sounds C4: the perceived pitch of its lowest cluster of partials
   (their power-weighted centre in log frequency, measured from the audio) within 5 cents of
   261.63 Hz;
4. a Scala tuning (19-TET) stored in the project plays every key at its tuned pitch, and the
   plugin state round-trips through the host (raw_state);
5. a torture run (issue 16): at 22.05-192 kHz and block sizes 1 to 4096, every parameter but
   the solver's set to a random value from the host before each span, 4000 notes a second,
   the state saved mid-note at one rate and restored at another, a reset while notes ring:
   the output stays finite and bounded, and the restored parameters are the saved ones.
Run by scripts/plugin-host-test.sh.
"""

import json
import re
import struct
import subprocess
import sys
import time

import mido
import numpy as np
import pedalboard._pedalboard as pedalboard_internals
from pedalboard import load_plugin

# nice-plug exposes MIDI CCs, channel pressure and pitch bend to VST3 hosts as 16 x 130 hidden
# parameters ("MIDI Ch. 1 CC 74", ...: how MPE reaches a VST3 plugin). pedalboard hides the
# ones JUCE plugins name "MIDI CC ..." through this set, but not these names, and building its
# Python wrapper of each parameter (it samples the value's text across the range) took about
# 35 s per 2,115 parameters, twice per plugin load: most of this test's time. The plugin still
# gets them from the host; only pedalboard's Python view skips them (checked in `main`).
MIDI_PARAM = re.compile(r"MIDI Ch\. \d+ ")
pedalboard_internals.PARAMETER_NAME_REGEXES_TO_IGNORE.add(MIDI_PARAM)

RATE = 48000
BUNDLE, CLI = sys.argv[1], sys.argv[2]


def modes(material, size="0.2"):
    out = subprocess.run(
        [CLI, "modes", "--shape", "bowl:d=16,wall=2", "--material", material,
         "--size", size, "--modes", "60", "--element", "hex27x2", "--json"],
        check=True, capture_output=True, text=True).stdout
    return np.array([m["freq_hz"] for m in json.loads(out)["modes"]])


def render(p, note, seconds=2.0):
    msgs = [mido.Message("note_on", note=note, velocity=100, time=0.0)]
    audio = p(msgs, duration=seconds, sample_rate=RATE, num_channels=2, buffer_size=512)
    return np.asarray(audio)[0]


def peaks(x, count):
    """Frequencies of the `count` strongest spectral peaks (parabolic interpolation), each the
    strongest within 3 % of itself.

    The window is the falling half of a Hann window: flat at the strike (a full Hann window
    would shape a fast-decaying wood note into t^2 e^(-dt) and split its peaks), smooth at the
    end (a ringing glass note is cut without side lobes)."""
    n = 1 << 18
    w = np.cos(0.5 * np.pi * np.arange(len(x)) / len(x)) ** 2
    spec = np.abs(np.fft.rfft(x * w, n))
    db = 20 * np.log10(spec + 1e-30)
    top = db.max()
    idx = [i for i in range(2, len(db) - 1)
           if db[i] > db[i - 1] and db[i] >= db[i + 1] and db[i] > top - 50]
    idx.sort(key=lambda i: -db[i])
    out = []
    for i in idx:
        a, b, c = db[i - 1], db[i], db[i + 1]
        off = 0.5 * (a - c) / (a - 2 * b + c)
        f = (i + off) * RATE / n
        # Only the strongest maximum within 3 %: two overlapping damped modes of a
        # near-degenerate pair (a bowl's) interfere, and with opposite phases their sum has a
        # weaker shoulder maximum just outside the pair that is no mode.
        if all(abs(f - g) > 0.03 * g for g in out):
            out.append(f)
        if len(out) == count:
            break
    return np.array(out)


def cluster_pitch(x):
    """The perceived pitch of the lowest cluster of partials: the power spectrum's centroid in
    log frequency over the band from 50 cents below the lowest strong peak (within 40 dB of
    the loudest) to 150 cents above it (the cluster is the partials within a semitone)."""
    n = 1 << 20
    w = np.cos(0.5 * np.pi * np.arange(len(x)) / len(x)) ** 2
    power = np.abs(np.fft.rfft(x * w, n)) ** 2
    f = np.arange(len(power)) * RATE / n
    db = 10 * np.log10(power + 1e-30)
    strong = [i for i in range(2, len(db) - 1)
              if db[i] > db[i - 1] and db[i] >= db[i + 1] and db[i] > db.max() - 40]
    low = f[min(strong)]
    band = (f > low * 2 ** (-50 / 1200)) & (f < low * 2 ** (150 / 1200))
    return float(np.exp(np.sum(power[band] * np.log(f[band])) / np.sum(power[band])))


ALPHA = ".ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+"
def state_json(raw):
    """The plugin's own state (nice-plug's JSON) inside JUCE's VST3 state blob: 'VC2!', the
    XML's length, then XML whose IComponent holds the bytes in JUCE's base64 variant (its
    own alphabet, 6 bits a character, least significant bit first), prefixed by the length."""
    i = raw.index(b"<?xml")
    xml = raw[i:].decode()
    enc = re.search(r"<IComponent>([^<]*)</IComponent>", xml).group(1)
    size, data = enc.split(".", 1)
    size = int(size)
    out = bytearray(size)
    pos = 0
    for c in data:
        v = ALPHA.index(c)
        for b in range(6):
            if v >> b & 1:
                byte, bit = divmod(pos, 8)
                if byte < size:
                    out[byte] |= 1 << bit
            pos += 1
    return bytes(out)
def with_state_json(raw, state):
    """`raw` with its plugin state replaced by `state` (inverse of `state_json`)."""
    chars = []
    nbits = len(state) * 8
    for start in range(0, nbits, 6):
        v = 0
        for b in range(6):
            pos = start + b
            if pos < nbits and state[pos // 8] >> (pos % 8) & 1:
                v |= 1 << b
        chars.append(ALPHA[v])
    enc = f"{len(state)}." + "".join(chars)
    i = raw.index(b"<?xml")
    xml = raw[i:].decode()
    xml = re.sub(r"<IComponent>[^<]*</IComponent>", f"<IComponent>{enc}</IComponent>", xml)
    body = xml.encode()
    # The header counts the XML as JUCE wrote it; keep its relation to the body's length.
    old = struct.unpack("<I", raw[4:8])[0]
    return raw[:4] + struct.pack("<I", old + len(body) - len(raw[i:])) + body


def nearest_error(fs, table):
    return np.array([np.min(np.abs(table - f)) / f for f in fs])


def main():
    p = load_plugin(BUNDLE)
    assert p.is_instrument, "not an instrument"
    names = list(p.parameters)
    midi = [c.name for c in p._parameters if MIDI_PARAM.match(c.name)]
    assert len(midi) == 16 * 130, f"{len(midi)} MIDI CC parameters, not 16 channels x 130"
    print("parameters:", ", ".join(names))
    p.key_mapping = "Positions"
    p.material = "Glass"
    time.sleep(0.5)
    render(p, 40, 0.2)  # activate: the first solve happens here
    x = render(p, 50)
    assert np.isfinite(x).all() and np.abs(x).max() > 0, "silent or NaN"
    glass = modes("glass")
    got = peaks(x, 8)
    err = nearest_error(got, glass)
    print("glass peaks (Hz):", np.round(got, 1), "max error vs modes:", f"{err.max():.2e}")
    assert err.max() < 0.01, f"peaks {got} not within 1% of modes {glass}"

    # Host parameter changes: a material with another Poisson's ratio (the worker re-solves;
    # give it time), then the size (voicing only).
    for material, size in [("Steel", 0.2), ("Steel", 0.1)]:
        p.material = material
        p.size_m = size
        render(p, 40, 0.2)
        time.sleep(3.0)
        y = render(p, 50)
        # The host quantises the value it sends (0.1 arrives as ~0.1004): use what it set.
        table = modes(material.lower(), repr(float(p.size_m)))
        got_s = peaks(y, 8)
        err_s = nearest_error(got_s, table)
        print(f"{material} {size} m peaks (Hz):", np.round(got_s, 1),
              "max error vs modes:", f"{err_s.max():.2e}")
        assert err_s.max() < 0.01, f"peaks {got_s} not within 1% of modes {table}"
        moved = nearest_error(got_s[:1], glass if size == 0.2 else modes("steel"))
        assert moved[0] > 0.01, f"the lowest peak {got_s[0]} did not move"

    # Pitch mapping: A4 plays the object scaled so that its fundamental is 440 Hz.
    p.key_mapping = "Pitch"
    z = render(p, 69)
    low = min(peaks(z, 6))
    print(f"pitch mapping: lowest strong peak {low:.2f} Hz for A4")
    assert abs(low - 440.0) / 440.0 < 0.01, low

    # The default bowl on C4: its lowest partials (a near-degenerate pair) are heard as one
    # tone at their power-weighted centre; that centre is the note (issue 19).
    p.material = "Glass"
    p.size_m = 0.2
    render(p, 40, 0.2)
    time.sleep(3.0)
    c4 = 440.0 * 2 ** (-9 / 12)
    pitch = cluster_pitch(render(p, 60, 6.0))
    cents = 1200 * np.log2(pitch / c4)
    print(f"default bowl on C4: perceived pitch {pitch:.2f} Hz ({cents:+.2f} cents)")
    assert abs(cents) < 5.0, f"C4 sounds {pitch:.2f} Hz, {cents:+.2f} cents off"

    # A Scala tuning in the project (issue 15): 19-tone equal temperament, loaded as the
    # editor stores it (the persisted "tuning" field), plays every key at 19-TET: keys 67 and
    # 79 (7 and 19 steps above middle C) at 2^(n/19) times middle C's measured pitch within
    # the 0.1 cent, and within 1 cent of 261.6256 * 2^(n/19) absolutely (12-TET would
    # put them 256 and 0 cents elsewhere). The absolute check is looser because this
    # measurement (the audio's power centroid over the bowl's pair) and the engine's pitch
    # reference (modal-force-weighted, ARCHITECTURE.md "The pitch a key plays") weigh the
    # pair's two partials a little differently (their decays differ): the same +0.15 cents
    # on every key, which the ratio to middle C cancels.
    raw = p.raw_state
    plugin_state = json.loads(state_json(raw))
    scl = "! 19edo\n19-EDO\n19\n" + "".join(f"{1200 * i / 19:.5f}\n" for i in range(1, 19))
    plugin_state["fields"]["tuning"] = json.dumps(
        {"scale_file": "19edo.scl", "scale": scl + "2/1\n", "mapping": None})
    p.raw_state = with_state_json(raw, json.dumps(plugin_state).encode())
    render(p, 40, 0.2)
    time.sleep(0.5)
    for key, steps in ((67, 7), (79, 19)):
        want = c4 * 2 ** (steps / 19)
        got = cluster_pitch(render(p, key, 6.0))
        off = 1200 * np.log2(got / want)
        step = 1200 * np.log2(got / pitch) - 1200 * steps / 19
        print(f"19-TET key {key}: {got:.3f} Hz, {off:+.3f} cents from {want:.3f} Hz, "
              f"{step:+.3f} cents from 2^({steps}/19) above middle C")
        assert abs(off) < 1.0, f"key {key} sounds {got:.3f} Hz, {off:+.3f} cents off"
        assert abs(step) < 0.1, f"key {key} is {step:+.3f} cents off 19-TET above middle C"
    p.raw_state = raw

    # State round trip through the host.
    state = p.raw_state
    p.material = "Wood"
    p.size_m = 0.5
    p.raw_state = state
    assert p.material == "Glass" and abs(p.size_m - 0.2) < 0.01, (p.material, p.size_m)

    torture(p)
    print("host test passed")


# Output bound of the torture run: 16 voices at +24 dB of a normalised strike (0.5 peak each)
# stay below 130; anything near this is a runaway.
TORTURE_BOUND = 1000.0

# Not fuzzed: each change of these re-solves the object (hex27 at 200 modes takes seconds);
# they are set from the host above, and the worker's coalescing is tested in the engine.
SOLVE_PARAMS = ("element", "modes", "solver", "answers")


def values(p):
    return {n: param.raw_value for n, param in p.parameters.items()}


def torture(p):
    rng = np.random.default_rng(16)
    params = p.parameters
    fuzzable = [n for n in params if n not in SOLVE_PARAMS]
    worst = 0.0
    spans = 0
    for rate in (22050, 44100, 96000, 192000):
        for block in (1, 17, 64, 512, 4096):
            for name in fuzzable:
                params[name].raw_value = float(rng.random())
            seconds = max(0.05, 2 * block / rate)
            # 4000 notes a second, random keys and velocities, with note-offs.
            count = int(4000 * seconds)
            msgs = []
            for i in range(count):
                t = i / 4000.0
                key = int(rng.integers(24, 108))
                msgs.append(mido.Message("note_on", note=key,
                                         velocity=int(rng.integers(1, 128)), time=t))
                msgs.append(mido.Message("note_off", note=key, velocity=0, time=t + 0.01))
            x = np.asarray(p(msgs, duration=seconds, sample_rate=rate, num_channels=2,
                             buffer_size=block, reset=False))
            assert np.isfinite(x).all(), f"NaN or inf at {rate} Hz, block {block}"
            worst = max(worst, float(np.abs(x).max()))
            assert worst < TORTURE_BOUND, f"output {worst} at {rate} Hz, block {block}"
            spans += 1
    # State saved mid-note at one rate, restored after playing at another: the parameters
    # come back bit-exact (the same values as right after restoring it the first time), and
    # it plays. (Values read back right after setting them from the host are the host's own
    # unquantised copy, not the plugin's, so the state is compared restore to restore.)
    p(
        [mido.Message("note_on", note=60, velocity=100, time=0.0)],
        duration=0.05, sample_rate=48000, num_channels=2, buffer_size=256, reset=False,
    )
    state = p.raw_state
    p.raw_state = state
    first = values(p)
    for name in [n for n in first if n not in SOLVE_PARAMS]:
        params[name].raw_value = float(rng.random())
    p([], duration=0.05, sample_rate=96000, num_channels=2, buffer_size=333, reset=False)
    p.raw_state = state
    again = values(p)
    diff = {n: (first[n], again[n]) for n in first if first[n] != again[n]}
    assert not diff, f"parameters not restored bit-exact: {diff}"
    # Reset while notes ring, then play on.
    p([mido.Message("note_on", note=64, velocity=127, time=0.0)],
      duration=0.02, sample_rate=44100, num_channels=2, buffer_size=64, reset=False)
    p.reset()
    y = np.asarray(p([mido.Message("note_on", note=67, velocity=90, time=0.0)],
                     duration=0.1, sample_rate=44100, num_channels=2, buffer_size=64,
                     reset=False))
    assert np.isfinite(y).all() and np.abs(y).max() < TORTURE_BOUND
    print(f"torture: {spans} spans at 22.05-192 kHz, blocks 1-4096, every parameter fuzzed, "
          f"peak {worst:.3g}; state restored across rates; reset while ringing")


if __name__ == "__main__":
    main()
