// dejag/data: video files, read and written frame by frame through OpenCV's videoio (FFmpeg).
//
// A video frame is an Image of 8-bit sRGB-encoded R, G, B (storage UInt8), as a PNG frame would be, so
// every single-frame method and every metric takes it unchanged. Writing is atomic like every other
// output (base/files.h): the encoder writes a temporary file beside the destination, which close() renames
// over it; a writer destroyed unclosed (an error, a signal) leaves no partial video.
//
// Codecs follow the extension unless named (--codec FOURCC): .mkv FFV1 (lossless: what measuring wants),
// .mp4/.m4v/.mov H.264 (avc1), .avi Motion JPEG. docs/video.md has the table.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "data/image.h"

namespace dejag {

// True for the extensions dejag reads and writes as video: .mp4 .m4v .mov .mkv .avi (any case).
bool isVideoPath(const std::string& path);

struct VideoInfo {
    int width = 0, height = 0;
    double fps = 0;          // frames per second as the container states it (0 if it states none)
    int64_t frameCount = 0;  // as the container states it: an estimate for some formats (0 if unknown)
    std::string codec;       // the FOURCC, e.g. "avc1", "FFV1"
};

class VideoReader {
  public:
    // Throws dejag::Error naming the file if it is missing or no decoder can open it.
    explicit VideoReader(const std::string& path);
    ~VideoReader();
    VideoReader(const VideoReader&) = delete;
    VideoReader& operator=(const VideoReader&) = delete;

    const VideoInfo& info() const { return info_; }
    // The next frame into `frame` (R, G, B, UInt8); false at the end. Throws if a frame's size changes.
    bool read(Image& frame);
    int64_t framesRead() const { return read_; }

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    std::string path_;
    VideoInfo info_;
    int64_t read_ = 0;
};

class VideoWriter {
  public:
    // codec: a FOURCC ("FFV1", "avc1", "mp4v", "MJPG"), or "" for the extension's default. Throws
    // dejag::Error naming the file if the folder cannot be written or the encoder refuses the codec.
    VideoWriter(const std::string& path, int width, int height, double fps, const std::string& codec = "");
    ~VideoWriter();
    VideoWriter(const VideoWriter&) = delete;
    VideoWriter& operator=(const VideoWriter&) = delete;

    // One frame: R, G, B (further channels ignored) holding sRGB-encoded values in [0, 1] (a linear-light
    // image, storage Half or Float, is encoded first), rounded to 8 bits.
    void write(const Image& frame);
    // Finishes the file and renames it into place. Without close(), nothing appears at `path`.
    void close();
    const std::string& codec() const { return codec_; }
    int64_t framesWritten() const { return written_; }

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    std::string path_, codec_;
    int width_ = 0, height_ = 0;
    int64_t written_ = 0;
};

// The codec the extension of `path` gets by default ("FFV1" for .mkv, ...).
std::string defaultVideoCodec(const std::string& path);

}  // namespace dejag
