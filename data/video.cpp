// Video files through OpenCV's videoio (FFmpeg backend): see data/video.h.
#include "data/video.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/videoio.hpp>

#include "base/error.h"
#include "base/files.h"

namespace dejag {
namespace {

namespace fs = std::filesystem;

std::string lowerExtension(const std::string& path) {
    std::string extension = fs::path(path).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return extension;
}

std::string fourccText(double value) {
    const int code = int(value);
    std::string text;
    for (int i = 0; i < 4; ++i) {
        const char c = char((code >> (8 * i)) & 0xff);
        text += (c >= 32 && c < 127) ? c : '?';
    }
    return code == 0 ? std::string() : text;
}

// FFmpeg and OpenCV report a codec they cannot use on the standard error of their own; dejag says it in
// one line instead. The descriptor is silenced for the call only (opening runs before any worker or
// progress bar writes there).
class QuietStandardError {
  public:
    QuietStandardError() {
        cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
        std::fflush(stderr);
        saved_ = ::dup(2);
        const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
        if (saved_ >= 0 && null >= 0) ::dup2(null, 2);
        if (null >= 0) ::close(null);
    }
    ~QuietStandardError() {
        if (saved_ < 0) return;
        ::dup2(saved_, 2);
        ::close(saved_);
    }
    QuietStandardError(const QuietStandardError&) = delete;
    QuietStandardError& operator=(const QuietStandardError&) = delete;

  private:
    int saved_ = -1;
};

}  // namespace

bool isVideoPath(const std::string& path) {
    const std::string e = lowerExtension(path);
    return e == ".mp4" || e == ".m4v" || e == ".mov" || e == ".mkv" || e == ".avi";
}

std::string defaultVideoCodec(const std::string& path) {
    const std::string e = lowerExtension(path);
    if (e == ".mkv") return "FFV1";
    if (e == ".avi") return "MJPG";
    return "avc1";
}

// ---- Reading ---------------------------------------------------------------------------------------------

struct VideoReader::Impl {
    cv::VideoCapture capture;
    cv::Mat bgr;
};

VideoReader::VideoReader(const std::string& path) : impl_(std::make_unique<Impl>()), path_(path) {
    requireReadableFile(path);
    {
        QuietStandardError quiet;
        impl_->capture.open(path, cv::CAP_FFMPEG);
    }
    if (!impl_->capture.isOpened()) throw Error("cannot read '" + path + "': not a video FFmpeg can decode");
    info_.width = int(impl_->capture.get(cv::CAP_PROP_FRAME_WIDTH));
    info_.height = int(impl_->capture.get(cv::CAP_PROP_FRAME_HEIGHT));
    info_.fps = impl_->capture.get(cv::CAP_PROP_FPS);
    if (!(info_.fps > 0 && info_.fps < 1e4)) info_.fps = 0;
    const double count = impl_->capture.get(cv::CAP_PROP_FRAME_COUNT);
    info_.frameCount = count > 0 && count < 1e12 ? int64_t(count) : 0;
    info_.codec = fourccText(impl_->capture.get(cv::CAP_PROP_FOURCC));
    if (info_.width <= 0 || info_.height <= 0 || int64_t(info_.width) * info_.height * 3 > kMaxImageSamples)
        throw Error("cannot read '" + path + "': implausible frame size " + std::to_string(info_.width) +
                    "x" + std::to_string(info_.height));
}

VideoReader::~VideoReader() = default;

bool VideoReader::read(Image& frame) {
    cv::Mat& bgr = impl_->bgr;
    if (!impl_->capture.read(bgr) || bgr.empty()) return false;
    if (bgr.cols != info_.width || bgr.rows != info_.height)
        throw Error("'" + path_ + "': frame " + std::to_string(read_) + " is " + std::to_string(bgr.cols) +
                    "x" + std::to_string(bgr.rows) + ", the video " + std::to_string(info_.width) + "x" +
                    std::to_string(info_.height));
    if (bgr.type() != CV_8UC3)
        throw Error("'" + path_ + "': frame " + std::to_string(read_) + " is not 8-bit colour");
    if (frame.width != bgr.cols || frame.height != bgr.rows || frame.channels() != 3)
        frame = Image(bgr.cols, bgr.rows, Image::defaultChannelNames(3), PixelType::UInt8);
    frame.storage = PixelType::UInt8;
    constexpr float kScale = 1.0f / 255.0f;
    for (int y = 0; y < bgr.rows; ++y) {
        const uint8_t* in = bgr.ptr<uint8_t>(y);
        float* out = frame.row(y);
        for (int x = 0; x < bgr.cols; ++x, in += 3, out += 3)
            out[0] = float(in[2]) * kScale, out[1] = float(in[1]) * kScale, out[2] = float(in[0]) * kScale;
    }
    ++read_;
    return true;
}

// ---- Writing ---------------------------------------------------------------------------------------------

struct VideoWriter::Impl {
    std::unique_ptr<AtomicFile> file;  // the temporary name the encoder writes, renamed by close()
    cv::VideoWriter writer;
    cv::Mat bgr;
};

VideoWriter::VideoWriter(const std::string& path, int width, int height, double fps, const std::string& codec)
    : impl_(std::make_unique<Impl>()),
      path_(path),
      codec_(codec.empty() ? defaultVideoCodec(path) : codec),
      width_(width),
      height_(height) {
    if (!isVideoPath(path))
        throw Error("cannot write '" + path + "': not a video extension (.mp4 .m4v .mov .mkv .avi)");
    if (codec_.size() != 4)
        throw Error("--codec '" + codec_ + "' is not a FOURCC (four characters: FFV1, avc1)");
    if (width <= 0 || height <= 0) throw Error("cannot write '" + path + "': empty frames");
    if (!(fps > 0 && fps < 1e4))
        throw Error("cannot write '" + path + "': frame rate " + std::to_string(fps));
    impl_->file = std::make_unique<AtomicFile>(path);
    const int fourcc = cv::VideoWriter::fourcc(codec_[0], codec_[1], codec_[2], codec_[3]);
    {
        QuietStandardError quiet;
        impl_->writer.open(impl_->file->temporaryPath(), cv::CAP_FFMPEG, fourcc, fps, cv::Size(width, height),
                           true);
    }
    if (!impl_->writer.isOpened())
        throw Error("cannot write '" + path + "': FFmpeg has no encoder for codec '" + codec_ + "' in a " +
                    lowerExtension(path) + " file");
    impl_->bgr.create(height, width, CV_8UC3);
}

VideoWriter::~VideoWriter() = default;  // unclosed: the AtomicFile removes the temporary file

void VideoWriter::write(const Image& frame) {
    if (!impl_->file) throw Error("cannot write '" + path_ + "': the video is already closed");
    if (frame.width != width_ || frame.height != height_ || frame.channels() < 3)
        throw Error("cannot write '" + path_ + "': frame " + std::to_string(written_) + " is " +
                    std::to_string(frame.width) + "x" + std::to_string(frame.height) + ", the video " +
                    std::to_string(width_) + "x" + std::to_string(height_));
    const bool linear = frame.storage == PixelType::Half || frame.storage == PixelType::Float;
    const size_t C = size_t(frame.channels());
    for (int y = 0; y < height_; ++y) {
        const float* in = frame.row(y);
        uint8_t* out = impl_->bgr.ptr<uint8_t>(y);
        for (int x = 0; x < width_; ++x, in += C, out += 3)
            for (int c = 0; c < 3; ++c) {
                float v = linear ? linearToSrgb(in[c]) : in[c];
                v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
                out[2 - c] = uint8_t(std::lround(v * 255.0f));
            }
    }
    impl_->writer.write(impl_->bgr);
    ++written_;
}

void VideoWriter::close() {
    if (!impl_->file) throw Error("cannot write '" + path_ + "': the video is already closed");
    impl_->writer.release();
    // The encoder reports no write error (a full disk): the finished file must open as a video of the
    // frames written before it replaces anything.
    const std::string temporary = impl_->file->temporaryPath();
    std::error_code error;
    const auto size = fs::file_size(temporary, error);
    if (error || size == 0) throw Error("cannot write '" + path_ + "': the encoder wrote nothing");
    {
        cv::VideoCapture check;
        {
            QuietStandardError quiet;
            check.open(temporary, cv::CAP_FFMPEG);
        }
        const double count = check.isOpened() ? check.get(cv::CAP_PROP_FRAME_COUNT) : -1;
        if (!check.isOpened() || (count > 0 && count + 1 < 0.9 * double(written_)))
            throw Error("cannot write '" + path_ + "': the finished video does not read back (a full disk?)");
    }
    impl_->file->commit();
    impl_->file.reset();
}

}  // namespace dejag
