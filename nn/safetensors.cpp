#include "nn/safetensors.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "base/error.h"
#include "base/files.h"

namespace dejag::nn {
namespace {

constexpr uint64_t kMaxHeaderBytes = 100u << 20;

static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE float and double expected");

uint64_t readLittleEndian64(const unsigned char* p) {
    uint64_t value = 0;
    for (int i = 7; i >= 0; --i) value = (value << 8) | p[i];
    return value;
}

}  // namespace

std::vector<float> StoredTensor::asFloat() const {
    if (dtype == "F32") return f32;
    return std::vector<float>(f64.begin(), f64.end());
}

std::vector<double> StoredTensor::asDouble() const {
    if (dtype == "F64") return f64;
    return std::vector<double>(f32.begin(), f32.end());
}

const StoredTensor& SafetensorsFile::at(const std::string& name) const {
    auto it = tensors.find(name);
    if (it == tensors.end()) throw Error("no tensor named '" + name + "'");
    return it->second;
}

SafetensorsFile parseSafetensors(const std::string& bytes, const std::string& file) {
    auto fail = [&](const std::string& what) {
        return Error("'" + file + "' is not a valid safetensors file: " + what);
    };
    if (bytes.size() < 8) throw fail("shorter than the 8-byte header length");
    const uint64_t headerBytes = readLittleEndian64(reinterpret_cast<const unsigned char*>(bytes.data()));
    if (headerBytes < 2 || headerBytes > kMaxHeaderBytes || headerBytes > bytes.size() - 8)
        throw fail("header length " + std::to_string(headerBytes) + " does not fit a " +
                   std::to_string(bytes.size()) + "-byte file");
    nlohmann::json header;
    try {
        header = nlohmann::json::parse(bytes.begin() + 8, bytes.begin() + 8 + std::ptrdiff_t(headerBytes));
    } catch (const nlohmann::json::exception& e) {
        throw fail(std::string("header is not JSON (") + e.what() + ")");
    }
    if (!header.is_object()) throw fail("header is not a JSON object");
    const uint64_t dataBegin = 8 + headerBytes, dataBytes = bytes.size() - dataBegin;

    SafetensorsFile result;
    std::vector<std::pair<uint64_t, uint64_t>> ranges;
    for (const auto& [name, entry] : header.items()) {
        if (name == "__metadata__") {
            if (!entry.is_object()) throw fail("__metadata__ is not an object");
            for (const auto& [key, value] : entry.items()) {
                if (!value.is_string()) throw fail("metadata '" + key + "' is not a string");
                result.metadata[key] = value.get<std::string>();
            }
            continue;
        }
        if (!entry.is_object() || !entry.contains("dtype") || !entry.contains("shape") ||
            !entry.contains("data_offsets"))
            throw fail("tensor '" + name + "' lacks dtype, shape or data_offsets");
        StoredTensor tensor;
        if (!entry["dtype"].is_string()) throw fail("tensor '" + name + "' has a non-string dtype");
        tensor.dtype = entry["dtype"].get<std::string>();
        if (tensor.dtype != "F32" && tensor.dtype != "F64")
            throw fail("tensor '" + name + "' has dtype " + tensor.dtype + " (dejag reads F32 and F64)");
        const auto& shape = entry["shape"];
        if (!shape.is_array() || shape.size() > 8) throw fail("tensor '" + name + "' has a bad shape");
        for (const auto& d : shape) {
            if (!d.is_number_integer() || d.get<int64_t>() < 0)
                throw fail("tensor '" + name + "' has a bad dimension");
            tensor.shape.push_back(d.get<int64_t>());
        }
        int64_t numel = 0;
        try {
            numel = shapeNumel(tensor.shape);
        } catch (const Error&) {
            throw fail("tensor '" + name + "' has an overflowing shape");
        }
        const auto& offsets = entry["data_offsets"];
        if (!offsets.is_array() || offsets.size() != 2 || !offsets[0].is_number_unsigned() ||
            !offsets[1].is_number_unsigned())
            throw fail("tensor '" + name + "' has bad data_offsets");
        const uint64_t begin = offsets[0].get<uint64_t>(), end = offsets[1].get<uint64_t>();
        const uint64_t elementBytes = tensor.dtype == "F32" ? 4 : 8;
        if (begin > end || end > dataBytes)
            throw fail("tensor '" + name + "' bytes [" + std::to_string(begin) + ", " + std::to_string(end) +
                       ") run past the " + std::to_string(dataBytes) + " data bytes (truncated file?)");
        if (end - begin != uint64_t(numel) * elementBytes)
            throw fail("tensor '" + name + "' has " + std::to_string(end - begin) + " bytes but shape " +
                       shapeToString(tensor.shape) + " needs " +
                       std::to_string(uint64_t(numel) * elementBytes));
        const char* source = bytes.data() + dataBegin + begin;
        if (tensor.dtype == "F32") {
            tensor.f32.resize(size_t(numel));
            std::memcpy(tensor.f32.data(), source, size_t(end - begin));
        } else {
            tensor.f64.resize(size_t(numel));
            std::memcpy(tensor.f64.data(), source, size_t(end - begin));
        }
        ranges.emplace_back(begin, end);
        result.tensors.emplace(name, std::move(tensor));
    }
    std::sort(ranges.begin(), ranges.end());
    for (size_t i = 1; i < ranges.size(); ++i)
        if (ranges[i].first < ranges[i - 1].second) throw fail("two tensors share bytes");
    return result;
}

SafetensorsFile readSafetensors(const std::string& path) {
    requireReadableFile(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot read '" + path + "'");
    std::ostringstream contents;
    contents << in.rdbuf();
    return parseSafetensors(contents.str(), path);
}

void writeSafetensors(const std::string& path, const std::vector<TensorToWrite>& tensors,
                      const std::map<std::string, std::string>& metadata) {
    nlohmann::ordered_json header;
    if (!metadata.empty()) header["__metadata__"] = metadata;
    uint64_t offset = 0;
    for (const TensorToWrite& t : tensors) {
        if (t.name.empty() || t.name == "__metadata__")
            throw Error("cannot write '" + path + "': bad tensor name");
        const uint64_t bytes = uint64_t(shapeNumel(t.shape)) * 4;
        header[t.name] = {{"dtype", "F32"}, {"shape", t.shape}, {"data_offsets", {offset, offset + bytes}}};
        offset += bytes;
    }
    std::string text = header.dump();
    while ((8 + text.size()) % 8) text += ' ';  // data starts 8-byte aligned
    AtomicFile out(path);
    unsigned char length[8];
    for (int i = 0; i < 8; ++i) length[i] = (uint64_t(text.size()) >> (8 * i)) & 0xff;
    out.write(length, 8);
    out.write(text);
    for (const TensorToWrite& t : tensors) out.write(t.data, size_t(shapeNumel(t.shape)) * 4);
    out.commit();
}

}  // namespace dejag::nn
