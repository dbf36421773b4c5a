#include "nn/optim.h"

#include <algorithm>
#include <cmath>

#include "base/error.h"

namespace dejag::nn {

OptimizerConfig::Kind OptimizerConfig::parseKind(const std::string& name) {
    if (name == "sgd") return Kind::Sgd;
    if (name == "adam") return Kind::Adam;
    if (name == "adamw") return Kind::AdamW;
    throw Error("unknown optimizer '" + name + "' (sgd, adam, adamw)");
}

Optimizer::Optimizer(const OptimizerConfig& config, int64_t parameterCount)
    : config_(config),
      m_(size_t(parameterCount), 0.0f),
      v_(config.kind == OptimizerConfig::Kind::Sgd ? 0 : size_t(parameterCount), 0.0f) {
    if (parameterCount < 0) throw Error("optimizer: negative parameter count");
}

void Optimizer::step(float* params, const float* grads, double learningRate) {
    ++steps_;
    const int64_t n = int64_t(m_.size());
    const double wd = config_.weightDecay;
    switch (config_.kind) {
        case OptimizerConfig::Kind::Sgd: {
            // PyTorch: buf = momentum * buf + g (buf = g on the first step); p -= lr * buf.
            const float momentum = float(config_.momentum), lr = float(learningRate);
            for (int64_t i = 0; i < n; ++i) {
                const float g = grads[i] + float(wd) * params[i];
                m_[i] = steps_ == 1 ? g : momentum * m_[i] + g;
                params[i] -= lr * m_[i];
            }
            break;
        }
        case OptimizerConfig::Kind::Adam:
        case OptimizerConfig::Kind::AdamW: {
            const bool decoupled = config_.kind == OptimizerConfig::Kind::AdamW;
            const float b1 = float(config_.beta1), b2 = float(config_.beta2);
            const double correction1 = 1.0 - std::pow(config_.beta1, double(steps_));
            const double correction2 = 1.0 - std::pow(config_.beta2, double(steps_));
            const float stepSize = float(learningRate / correction1);
            const float sqrtCorrection2 = float(std::sqrt(correction2));
            const float eps = float(config_.epsilon), decay = float(learningRate * wd);
            for (int64_t i = 0; i < n; ++i) {
                float g = grads[i];
                if (decoupled)
                    params[i] *= 1.0f - decay;
                else
                    g += float(wd) * params[i];
                m_[i] = b1 * m_[i] + (1.0f - b1) * g;
                v_[i] = b2 * v_[i] + (1.0f - b2) * g * g;
                const float denominator = std::sqrt(v_[i]) / sqrtCorrection2 + eps;
                params[i] -= stepSize * m_[i] / denominator;
            }
            break;
        }
    }
}

double LrSchedule::rateAt(int64_t step) const {
    double rate = baseRate;
    switch (kind) {
        case Kind::Constant:
            break;
        case Kind::Step:
            rate = baseRate * std::pow(gamma, double(step / std::max<int64_t>(1, stepEvery)));
            break;
        case Kind::Cosine: {
            const double t = std::clamp(double(step) / double(std::max<int64_t>(1, totalSteps)), 0.0, 1.0);
            rate = minRate + 0.5 * (baseRate - minRate) * (1.0 + std::cos(M_PI * t));
            break;
        }
    }
    if (warmupSteps > 0 && step < warmupSteps) rate *= double(step + 1) / double(warmupSteps);
    return rate;
}

double gradientNorm(const float* grads, int64_t n) {
    double sum = 0.0;
    for (int64_t i = 0; i < n; ++i) sum += double(grads[i]) * grads[i];
    return std::sqrt(sum);
}

double clipGradientNorm(float* grads, int64_t n, double maxNorm) {
    const double norm = gradientNorm(grads, n);
    if (norm > maxNorm) {
        const float factor = float(maxNorm / (norm + 1e-6));
        for (int64_t i = 0; i < n; ++i) grads[i] *= factor;
    }
    return norm;
}

}  // namespace dejag::nn
