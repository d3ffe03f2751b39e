"""mimic_audio's recogniser: PyPI pocketsphinx (5.1.1, the CMU en-US acoustic model and its phone
language model ship inside the wheel: nothing is downloaded at run time).

Reads 16 kHz mono signed 16-bit little-endian PCM on stdin. Prints one JSON object:
  {"phones": [[PHONE, start_frame, end_frame], ...]}   free phone recognition, 10 ms frames
  "words": [[WORD, [PHONE, ...]], ...]                 with --words: each word's pronunciation from
                                                       the model's CMU dictionary (letters for a word
                                                       it lacks, listed in "oov")
mimic_audio runs it with `python -c` (the text is compiled into the crate) and reads the JSON.
"""
import json
import os
import re
import sys


def letters(word):
    """A rough pronunciation of a word the dictionary lacks, letter by letter."""
    table = {"a": "AE", "e": "EH", "i": "IH", "o": "AA", "u": "AH", "y": "IY", "b": "B",
             "c": "K", "d": "D", "f": "F", "g": "G", "h": "HH", "j": "JH", "k": "K", "l": "L",
             "m": "M", "n": "N", "p": "P", "q": "K", "r": "R", "s": "S", "t": "T", "v": "V",
             "w": "W", "x": "K", "z": "Z"}
    return [table[c] for c in word if c in table]


def main():
    try:
        import pocketsphinx
    except ImportError as e:
        print(json.dumps({"error": "cannot import pocketsphinx (pip install pocketsphinx==5.1.1): %s" % e}))
        return 0
    args = sys.argv[1:]
    words = args[args.index("--words") + 1:] if "--words" in args else None
    pcm = sys.stdin.buffer.read()
    model = os.path.join(pocketsphinx.get_model_path(), "en-us")
    out = {"phones": []}
    if len(pcm) >= 3200:
        d = pocketsphinx.Decoder(hmm=os.path.join(model, "en-us"),
                                 allphone=os.path.join(model, "en-us-phone.lm.bin"),
                                 lw=2.0, pip=0.3, beam=1e-20, pbeam=1e-20,
                                 samprate=16000, loglevel="FATAL")
        d.start_utt()
        d.process_raw(pcm, full_utt=True)
        d.end_utt()
        out["phones"] = [[s.word, s.start_frame, s.end_frame] for s in d.seg()]
    if words is not None:
        pron = {}
        wanted = {re.sub(r"[^a-z']", "", w.lower()) for w in words}
        with open(os.path.join(model, "cmudict-en-us.dict"), encoding="utf-8") as f:
            for line in f:
                parts = line.split()
                if parts and parts[0] in wanted and parts[0] not in pron:
                    pron[parts[0]] = parts[1:]
        out["words"], out["oov"] = [], []
        for w in words:
            key = re.sub(r"[^a-z']", "", w.lower())
            if not key:
                continue
            if key not in pron:
                out["oov"].append(w)
            out["words"].append([w, pron.get(key) or letters(key)])
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
