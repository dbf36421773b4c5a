"""The golden fixtures' file format (read by nn::readSafetensors in the C++ tests): F32 and F64 arrays
under their names, the case's configuration as JSON in the metadata key "config"."""
import json
import struct

import numpy as np


def write_safetensors(path, arrays, config):
    header = {"__metadata__": {"config": json.dumps(config, sort_keys=True)}}
    blobs, offset = [], 0
    for name, a in arrays.items():
        dtype = {np.dtype(np.float32): "F32", np.dtype(np.float64): "F64"}[a.dtype]
        data = np.ascontiguousarray(a).astype("<f4" if dtype == "F32" else "<f8").tobytes()
        header[name] = {"dtype": dtype, "shape": list(a.shape), "data_offsets": [offset, offset + len(data)]}
        blobs.append(data)
        offset += len(data)
    text = json.dumps(header).encode()
    text += b" " * ((8 - (8 + len(text)) % 8) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(text)))
        f.write(text)
        for b in blobs:
            f.write(b)
