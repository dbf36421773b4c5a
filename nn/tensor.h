// dejag/nn: the tensor — float32, NCHW, 64-byte aligned, shape-checked.
//
// A Tensor owns its storage (or views storage owned elsewhere, e.g. one slice of the flat parameter
// buffer) and knows its shape; layers take raw pointers plus a small descriptor, so the same kernels run
// on float tensors in training and on double buffers in gradient checks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

namespace dejag::nn {

using Shape = std::vector<int64_t>;

std::string shapeToString(const Shape& shape);  // "(8, 32, 128, 128)"
int64_t shapeNumel(const Shape& shape);         // throws dejag::Error on a negative or overflowing dimension

// Storage aligned to 64 bytes (one cache line, one AVX-512 vector).
struct AlignedFree {
    void operator()(float* p) const;
};
std::unique_ptr<float[], AlignedFree> allocateAligned(size_t count);

class Tensor {
  public:
    Tensor() = default;
    explicit Tensor(Shape shape);  // zero-filled, owning
    Tensor(std::initializer_list<int64_t> shape) : Tensor(Shape(shape)) {}
    static Tensor view(float* data, Shape shape);  // non-owning view

    Tensor(Tensor&&) noexcept = default;
    Tensor& operator=(Tensor&&) noexcept = default;
    Tensor clone() const;  // deep, owning copy

    const Shape& shape() const { return shape_; }
    int64_t dim(int i) const;  // negative i counts from the end
    int rank() const { return int(shape_.size()); }
    int64_t numel() const { return numel_; }
    size_t byteSize() const { return size_t(numel_) * sizeof(float); }
    float* data() { return data_; }
    const float* data() const { return data_; }
    bool empty() const { return numel_ == 0; }

    // Element (n, c, h, w) of a rank-4 tensor.
    float& at(int64_t n, int64_t c, int64_t h, int64_t w) {
        return data_[((n * shape_[1] + c) * shape_[2] + h) * shape_[3] + w];
    }
    float at(int64_t n, int64_t c, int64_t h, int64_t w) const {
        return data_[((n * shape_[1] + c) * shape_[2] + h) * shape_[3] + w];
    }

    void fill(float value);
    void zero() { fill(0.0f); }
    // Throws dejag::Error "<what>: expected shape (..), got (..)" unless the shape matches.
    void requireShape(const Shape& expected, const std::string& what) const;
    // First non-finite element, or -1.
    int64_t findNonFinite() const;

  private:
    Shape shape_;
    int64_t numel_ = 0;
    std::unique_ptr<float[], AlignedFree> storage_;
    float* data_ = nullptr;
};

}  // namespace dejag::nn
