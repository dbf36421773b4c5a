#include "nn/tensor.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>

#include "base/error.h"

namespace dejag::nn {

std::string shapeToString(const Shape& shape) {
    std::string text = "(";
    for (size_t i = 0; i < shape.size(); ++i) text += (i ? ", " : "") + std::to_string(shape[i]);
    return text + ")";
}

int64_t shapeNumel(const Shape& shape) {
    int64_t count = 1;
    for (int64_t d : shape) {
        if (d < 0) throw Error("tensor shape " + shapeToString(shape) + " has a negative dimension");
        if (d != 0 && count > std::numeric_limits<int64_t>::max() / 8 / d)
            throw Error("tensor shape " + shapeToString(shape) + " is too large");
        count *= d;
    }
    return count;
}

void AlignedFree::operator()(float* p) const {
    std::free(p);
}

std::unique_ptr<float[], AlignedFree> allocateAligned(size_t count) {
    const size_t bytes = ((count * sizeof(float) + 63) / 64) * 64;
    void* p = std::aligned_alloc(64, bytes == 0 ? 64 : bytes);
    if (!p) throw std::bad_alloc();
    return std::unique_ptr<float[], AlignedFree>(static_cast<float*>(p));
}

Tensor::Tensor(Shape shape) : shape_(std::move(shape)), numel_(shapeNumel(shape_)) {
    storage_ = allocateAligned(size_t(numel_));
    data_ = storage_.get();
    std::memset(data_, 0, byteSize());
}

Tensor Tensor::view(float* data, Shape shape) {
    Tensor t;
    t.shape_ = std::move(shape);
    t.numel_ = shapeNumel(t.shape_);
    t.data_ = data;
    return t;
}

Tensor Tensor::clone() const {
    Tensor copy(shape_);
    if (numel_) std::memcpy(copy.data_, data_, byteSize());
    return copy;
}

int64_t Tensor::dim(int i) const {
    const int r = rank();
    if (i < 0) i += r;
    if (i < 0 || i >= r)
        throw Error("dimension " + std::to_string(i) + " of a rank-" + std::to_string(r) + " tensor");
    return shape_[size_t(i)];
}

void Tensor::fill(float value) {
    for (int64_t i = 0; i < numel_; ++i) data_[i] = value;
}

void Tensor::requireShape(const Shape& expected, const std::string& what) const {
    if (shape_ != expected)
        throw Error(what + ": expected shape " + shapeToString(expected) + ", got " + shapeToString(shape_));
}

int64_t Tensor::findNonFinite() const {
    for (int64_t i = 0; i < numel_; ++i)
        if (!std::isfinite(data_[i])) return i;
    return -1;
}

}  // namespace dejag::nn
