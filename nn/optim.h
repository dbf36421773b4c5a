// dejag/nn: optimizers over one flat parameter buffer, learning-rate schedules, gradient clipping.
//
// All parameters of a model live in one contiguous buffer (views into it are the layers' weights), and
// so do their gradients: an optimizer step is one flat loop. Formulas follow PyTorch's SGD, Adam and
// AdamW exactly, so the golden tests can compare step by step.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace dejag::nn {

struct OptimizerConfig {
    enum class Kind { Sgd, Adam, AdamW } kind = Kind::Adam;
    double learningRate = 1e-3;
    double momentum = 0.9;              // SGD
    double beta1 = 0.9, beta2 = 0.999;  // Adam, AdamW
    double epsilon = 1e-8;
    double weightDecay = 0.0;                        // SGD/Adam: L2 added to the gradient; AdamW: decoupled
    static Kind parseKind(const std::string& name);  // sgd, adam, adamw
};

class Optimizer {
  public:
    Optimizer(const OptimizerConfig& config, int64_t parameterCount);
    // One update of params (n) from grads (n) with learning rate lr (from a schedule).
    void step(float* params, const float* grads, double learningRate);
    int64_t steps() const { return steps_; }
    const OptimizerConfig& config() const { return config_; }
    // Optimizer state, for checkpoints: first and second moments (or the momentum buffer) and the count.
    std::vector<float>& firstMoment() { return m_; }
    std::vector<float>& secondMoment() { return v_; }
    const std::vector<float>& firstMoment() const { return m_; }
    const std::vector<float>& secondMoment() const { return v_; }
    void setSteps(int64_t steps) { steps_ = steps; }

  private:
    OptimizerConfig config_;
    std::vector<float> m_, v_;
    int64_t steps_ = 0;
};

struct LrSchedule {
    enum class Kind { Constant, Step, Cosine } kind = Kind::Constant;
    double baseRate = 1e-3;
    int64_t warmupSteps = 0;   // linear ramp from baseRate / warmupSteps up to baseRate
    int64_t stepEvery = 1000;  // Step: multiply by gamma every stepEvery steps
    double gamma = 0.5;
    int64_t totalSteps = 10000;  // Cosine: from baseRate down to minRate at totalSteps
    double minRate = 0.0;
    double rateAt(int64_t step) const;  // step counts from 0
};

// Scales grads so that their global L2 norm is at most maxNorm (PyTorch clip_grad_norm_:
// factor maxNorm / (norm + 1e-6)). Returns the norm before clipping (computed in double).
double clipGradientNorm(float* grads, int64_t n, double maxNorm);
double gradientNorm(const float* grads, int64_t n);

}  // namespace dejag::nn
