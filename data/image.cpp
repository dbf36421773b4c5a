#include "data/image.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>

#include "base/error.h"
#include "base/files.h"
#include "base/srgb.h"

// Leak-sanitizer builds: OpenImageIO 2.4's PNG reader leaks the error message of every truncated file
// (a std::string longjmp'd over inside PngReadCallback). Allocations made inside OpenImageIO's readers
// are left out of leak detection here, so the sanitizers can keep their fast default unwinder (the slow
// one a stack-matching suppression needs deadlocks against llvmpipe's JIT registering its frames).
#if defined(__SANITIZE_ADDRESS__)
#define DEJAG_LSAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define DEJAG_LSAN 1
#endif
#endif
#if defined(DEJAG_LSAN)
#include <sanitizer/lsan_interface.h>
#endif
#if defined(DEJAG_LSAN) || defined(__SANITIZE_THREAD__)
#define DEJAG_SANITIZER_REPORTS 1
#include <sanitizer/common_interface_defs.h>
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define DEJAG_SANITIZER_REPORTS 1
#include <sanitizer/common_interface_defs.h>
#endif
#endif

namespace dejag {
namespace {

// Refuse headers that would need absurd memory: a corrupt file must not become a 100 GB allocation.
constexpr int64_t kMaxSide = 65536;

// libpng and libjpeg print their own complaints to stderr, then OpenImageIO reports the same failure
// through its error queue, which becomes dejag's one error line. While any codec runs, stderr points at
// /dev/null (reference-counted, so concurrent reads do not serialise).
// Leaves the allocations of its scope out of leak detection (leak-sanitizer builds only).
class ThirdPartyLeaksIgnored {
  public:
#if defined(DEJAG_LSAN)
    ThirdPartyLeaksIgnored() {
        __lsan_disable();
    }
    ~ThirdPartyLeaksIgnored() {
        __lsan_enable();
    }
#endif
    ThirdPartyLeaksIgnored(const ThirdPartyLeaksIgnored&) = delete;
    ThirdPartyLeaksIgnored& operator=(const ThirdPartyLeaksIgnored&) = delete;
#if !defined(DEJAG_LSAN)
    ThirdPartyLeaksIgnored() = default;
#endif
};

// OpenEXR 3.1 trusts the sizes its header declares: an attribute claiming 500 MB in a 300-byte file is
// allocated and cleared before the read fails (and a data window of 2^31 rows sizes the line-offset
// table). Before OpenImageIO opens a file that starts with the EXR magic number, its headers are walked
// here: every attribute must fit in the bytes the file has left, and every part's data window must fit
// the sample budget. Anything else (names, types, values) is left to OpenEXR.
void checkExrHeaders(const std::string& path, int64_t maxSamples) {
    std::FILE* file = std::fopen(path.c_str(), "rb");
    if (!file) return;  // requireReadableFile has already reported a missing file
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> closer(file, &std::fclose);
    unsigned char prefix[8];
    if (std::fread(prefix, 1, 8, file) != 8 || prefix[0] != 0x76 || prefix[1] != 0x2f || prefix[2] != 0x31 ||
        prefix[3] != 0x01)
        return;  // not an EXR: its own reader judges it
    std::error_code ignored;
    const int64_t fileSize = int64_t(std::filesystem::file_size(path, ignored));
    const bool multipart = (prefix[5] & 0x10) != 0;  // version flag bit 12
    const auto corrupt = [&](const std::string& what) {
        return Error("cannot read '" + path + "': corrupt EXR header (" + what + ")");
    };
    // Reads a NUL-terminated name of at most 255 characters; empty marks the end of a header (list).
    const auto readName = [&]() {
        std::string name;
        for (int c; (c = std::fgetc(file)) != 0;) {
            if (c == EOF) throw corrupt("the file ends inside the header");
            if (name.size() == 255) throw corrupt("an attribute name longer than 255 characters");
            name.push_back(char(c));
        }
        return name;
    };
    for (int part = 0;; ++part) {
        std::string name = readName();
        if (name.empty()) {
            if (part == 0) throw corrupt("an empty header");
            return;  // the empty header that ends a multi-part file's list
        }
        for (; !name.empty(); name = readName()) {
            const std::string type = readName();
            unsigned char sizeBytes[4];
            if (std::fread(sizeBytes, 1, 4, file) != 4) throw corrupt("the file ends inside the header");
            const int32_t size = int32_t(uint32_t(sizeBytes[0]) | uint32_t(sizeBytes[1]) << 8 |
                                         uint32_t(sizeBytes[2]) << 16 | uint32_t(sizeBytes[3]) << 24);
            const int64_t left = fileSize - int64_t(std::ftell(file));
            if (size < 0 || size > left)
                throw corrupt("attribute '" + name + "' claims " + std::to_string(size) +
                              " bytes, the file has " + std::to_string(left) + " left");
            if (name == "dataWindow" && type == "box2i" && size == 16) {
                unsigned char box[16];
                if (std::fread(box, 1, 16, file) != 16) throw corrupt("the file ends inside the header");
                int32_t corner[4];
                for (int i = 0; i < 4; ++i)
                    corner[i] = int32_t(uint32_t(box[4 * i]) | uint32_t(box[4 * i + 1]) << 8 |
                                        uint32_t(box[4 * i + 2]) << 16 | uint32_t(box[4 * i + 3]) << 24);
                const int64_t width = int64_t(corner[2]) - corner[0] + 1,
                              height = int64_t(corner[3]) - corner[1] + 1;
                if (width <= 0 || height <= 0)
                    throw corrupt("data window " + std::to_string(width) + "x" + std::to_string(height));
                if (width > kMaxSide || height > kMaxSide ||
                    width * height > std::min(maxSamples, kMaxImageSamples))
                    throw Error("cannot read '" + path + "': " + std::to_string(width) + "x" +
                                std::to_string(height) + " is larger than dejag accepts");
            } else if (std::fseek(file, size, SEEK_CUR) != 0) {
                throw corrupt("the file ends inside the header");
            }
        }
        if (!multipart) return;
    }
}

// A sanitizer's report from inside a codec goes to the real stderr (found fuzzing: an out-of-memory
// report vanished into /dev/null). Fuzzing builds do not silence stderr at all: libFuzzer reports there.
class QuietStderr {
  public:
#if !defined(DEJAG_FUZZING)
    QuietStderr() {
        std::lock_guard<std::mutex> lock(mutex_);
        if (users_++ > 0) return;
        std::fflush(stderr);
        saved_ = ::dup(STDERR_FILENO);
        const int devNull = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
        if (saved_ >= 0 && devNull >= 0) ::dup2(devNull, STDERR_FILENO);
        if (devNull >= 0) ::close(devNull);
#if defined(DEJAG_SANITIZER_REPORTS)
        if (saved_ >= 0) __sanitizer_set_report_fd(reinterpret_cast<void*>(intptr_t(saved_)));
#endif
    }
    ~QuietStderr() {
        std::lock_guard<std::mutex> lock(mutex_);
        if (--users_ > 0) return;
        std::fflush(stderr);
#if defined(DEJAG_SANITIZER_REPORTS)
        __sanitizer_set_report_fd(reinterpret_cast<void*>(intptr_t(STDERR_FILENO)));
#endif
        if (saved_ >= 0) {
            ::dup2(saved_, STDERR_FILENO);
            ::close(saved_);
        }
        saved_ = -1;
    }
#else
    QuietStderr() = default;
#endif
    QuietStderr(const QuietStderr&) = delete;
    QuietStderr& operator=(const QuietStderr&) = delete;

  private:
    static inline std::mutex mutex_;
    static inline int users_ = 0;
    static inline int saved_ = -1;
};

std::string oneLine(std::string text) {
    std::replace(text.begin(), text.end(), '\n', ' ');
    while (!text.empty() && (text.back() == ' ' || text.back() == '.')) text.pop_back();
    return text.empty() ? "unknown error" : text;
}

PixelType pixelTypeOf(const OIIO::TypeDesc& format) {
    switch (format.basetype) {
        case OIIO::TypeDesc::UINT8:
        case OIIO::TypeDesc::INT8:
            return PixelType::UInt8;
        case OIIO::TypeDesc::UINT16:
        case OIIO::TypeDesc::INT16:
            return PixelType::UInt16;
        case OIIO::TypeDesc::HALF:
            return PixelType::Half;
        default:
            return PixelType::Float;
    }
}

OIIO::TypeDesc typeDescOf(PixelType type) {
    switch (type) {
        case PixelType::UInt8:
            return OIIO::TypeDesc::UINT8;
        case PixelType::UInt16:
            return OIIO::TypeDesc::UINT16;
        case PixelType::Half:
            return OIIO::TypeDesc::HALF;
        case PixelType::Float:
            return OIIO::TypeDesc::FLOAT;
    }
    return OIIO::TypeDesc::FLOAT;
}

std::string lowerExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

// The pixel type a format can hold that is closest to `wanted`.
PixelType storableType(const std::string& extension, PixelType wanted) {
    const bool integerOnly = extension == ".png" || extension == ".jpg" || extension == ".jpeg" ||
                             extension == ".ppm" || extension == ".pgm" || extension == ".bmp";
    if (extension == ".jpg" || extension == ".jpeg" || extension == ".bmp") return PixelType::UInt8;
    if (integerOnly) return wanted == PixelType::UInt8 ? PixelType::UInt8 : PixelType::UInt16;
    if (extension == ".exr") {
        // EXR stores half, float or uint32: 8-bit values survive half exactly enough to round back.
        if (wanted == PixelType::UInt8) return PixelType::Half;
        if (wanted == PixelType::UInt16) return PixelType::Float;
    }
    return wanted;
}

// "C7". Appending avoids GCC 12's false -Wrestrict on "literal" + std::string (GCC bug 105651).
std::string numberedChannelName(int channel) {
    std::string name = "C";
    name += std::to_string(channel);
    return name;
}

std::string_view baseChannelName(std::string_view name) {
    size_t dot = name.rfind('.');
    return dot == std::string_view::npos ? name : name.substr(dot + 1);
}

bool isColourChannel(std::string_view name) {
    std::string_view base = baseChannelName(name);
    return base == "R" || base == "G" || base == "B" || base == "Y";
}

template <class Transfer>
void convertColourChannels(Image& image, Transfer transfer) {
    const int channels = image.channels();
    std::vector<int> colour;
    for (int c = 0; c < channels; ++c)
        if (isColourChannel(image.channelNames[c])) colour.push_back(c);
    for (size_t p = 0; p < image.pixelCount(); ++p)
        for (int c : colour) image.pixels[p * channels + c] = transfer(image.pixels[p * channels + c]);
}

}  // namespace

const char* pixelTypeName(PixelType type) {
    switch (type) {
        case PixelType::UInt8:
            return "uint8";
        case PixelType::UInt16:
            return "uint16";
        case PixelType::Half:
            return "half";
        case PixelType::Float:
            return "float";
    }
    return "unknown";
}

bool holdsLinearLight(PixelType type) {
    return type == PixelType::Half || type == PixelType::Float;
}

double valueScale(PixelType type) {
    switch (type) {
        case PixelType::UInt8:
            return 255.0;
        case PixelType::UInt16:
            return 65535.0;
        default:
            return 1.0;
    }
}

Image::Image(int w, int h, std::vector<std::string> names, PixelType storageType)
    : width(w), height(h), channelNames(std::move(names)), storage(storageType) {
    if (w < 0 || h < 0 || channelNames.empty())
        throw Error("an image needs a size >= 0 and at least one channel");
    pixels.assign(sampleCount(), 0.0f);
}

std::vector<std::string> Image::defaultChannelNames(int channels) {
    switch (channels) {
        case 1:
            return {"Y"};
        case 2:
            return {"Y", "A"};
        case 3:
            return {"R", "G", "B"};
        case 4:
            return {"R", "G", "B", "A"};
        default: {
            std::vector<std::string> names;
            for (int c = 0; c < channels; ++c) names.push_back(numberedChannelName(c));
            return names;
        }
    }
}

int Image::findChannel(std::string_view name) const {
    for (int c = 0; c < channels(); ++c)
        if (channelNames[c] == name) return c;
    return -1;
}

Image selectChannels(const Image& image, const std::vector<std::string>& names) {
    std::vector<int> sources;
    for (const std::string& name : names) {
        const int c = image.findChannel(name);
        if (c < 0) throw Error("the image (" + image.describe() + ") has no channel " + name);
        sources.push_back(c);
    }
    Image selected(image.width, image.height, names, image.storage);
    const size_t from = size_t(image.channels()), to = names.size();
    for (size_t pixel = 0; pixel < image.pixelCount(); ++pixel)
        for (size_t c = 0; c < to; ++c)
            selected.pixels[pixel * to + c] = image.pixels[pixel * from + sources[c]];
    return selected;
}

std::string Image::channelList() const {
    std::string names;
    for (int c = 0; c < channels(); ++c) names += (c ? "," : "") + channelNames[c];
    return names;
}

std::string Image::describe() const {
    const std::string names = channelList();
    return std::to_string(width) + "x" + std::to_string(height) + ", " + std::to_string(channels()) +
           (channels() == 1 ? " channel (" : " channels (") + names + "), " + pixelTypeName(storage);
}

Image readImage(const std::string& path, int64_t maxSamples) {
    requireReadableFile(path);
    checkExrHeaders(path, maxSamples);
    // A file is read by the reader its extension names, or not at all: by default OpenImageIO would go
    // on to offer a file its reader rejects to every other format's reader, which costs time and gives a
    // corrupt file more code to break (found fuzzing: a 21-byte ".exr" made the WebP reader allocate
    // 16 MB), and the error a user sees would come from whichever reader failed last.
    static const bool extensionReaderOnly = OIIO::attribute("try_all_readers", 0);
    (void)extensionReaderOnly;
    QuietStderr quiet;
    [[maybe_unused]] const ThirdPartyLeaksIgnored oiioLeaks;
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);  // keep stored values exactly (no premultiplication)
    auto input = OIIO::ImageInput::open(path, &config);
    if (!input) throw Error("cannot read '" + path + "': " + oneLine(OIIO::geterror()));
    const OIIO::ImageSpec& spec = input->spec();
    if (spec.deep) throw Error("cannot read '" + path + "': deep images are not supported");
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1)
        throw Error("cannot read '" + path + "': implausible header (" + std::to_string(spec.width) + "x" +
                    std::to_string(spec.height) + ", " + std::to_string(spec.nchannels) + " channels)");
    if (spec.width > kMaxSide || spec.height > kMaxSide ||
        int64_t(spec.width) * spec.height * spec.nchannels > std::min(maxSamples, kMaxImageSamples))
        throw Error("cannot read '" + path + "': " + std::to_string(spec.width) + "x" +
                    std::to_string(spec.height) + "x" + std::to_string(spec.nchannels) +
                    " is larger than dejag accepts");

    std::vector<std::string> names(spec.channelnames.begin(), spec.channelnames.end());
    if (int(names.size()) != spec.nchannels) names = Image::defaultChannelNames(spec.nchannels);
    for (int c = 0; c < spec.nchannels; ++c)
        if (names[c].empty()) names[c] = numberedChannelName(c);

    Image image;
    image.width = spec.width, image.height = spec.height, image.channelNames = std::move(names);
    image.storage = pixelTypeOf(spec.format);
    // Per-channel formats (EXR with half colour and float depth): remember the widest.
    for (const OIIO::TypeDesc& channelFormat : spec.channelformats)
        if (pixelTypeOf(channelFormat) == PixelType::Float) image.storage = PixelType::Float;
    // Address space for the whole image, but memory only for the rows actually read: a short corrupt
    // file whose header claims a large image fails at its first missing rows instead of first clearing
    // the whole buffer (found by fuzz/fuzz_image.cpp: 300 bytes cost 1 GiB and a second).
    const size_t rowSamples = size_t(spec.width) * size_t(spec.nchannels);
    image.pixels.reserve(rowSamples * size_t(spec.height));
    if (spec.tile_width > 0) {
        image.pixels.resize(rowSamples * size_t(spec.height));
        if (!input->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data()))
            throw Error("cannot read '" + path + "': " + oneLine(input->geterror()));
    } else {
        // Rows are read in chunks of about 16 MB of floats (at least 64 rows): OpenImageIO 2.4 allocates a
        // 64 MB conversion buffer on every read_scanlines call whatever its size, which 64-row chunks
        // paid 17 times per 1080p frame (found fuzzing: a 250-byte TIFF of 8 × 29,446 pixels took 460
        // reads, > 10 s under ASan, whose allocator poisons each buffer's shadow).
        const size_t rowBytes = rowSamples * sizeof(float);
        const int rowsPerRead =
            int(std::min<size_t>(size_t(spec.height), std::max<size_t>(64, (size_t(16) << 20) / rowBytes)));
        for (int y = 0; y < spec.height; y += rowsPerRead) {
            const int last = std::min(spec.height, y + rowsPerRead);
            image.pixels.resize(rowSamples * size_t(last));
            // (Some readers report a short file only through the error queue, and read on.)
            if (!input->read_scanlines(0, 0, spec.y + y, spec.y + last, 0, 0, spec.nchannels,
                                       OIIO::TypeDesc::FLOAT, image.pixels.data() + rowSamples * size_t(y)) ||
                input->has_error())
                throw Error("cannot read '" + path + "': " + oneLine(input->geterror()));
        }
    }
    // Some readers report a truncated file only through the error queue.
    if (input->has_error()) throw Error("cannot read '" + path + "': " + oneLine(input->geterror()));
    input->close();
    return image;
}

void writeImage(const std::string& path, const Image& image, const WriteOptions& options) {
    if (image.width <= 0 || image.height <= 0 || image.channels() <= 0)
        throw Error("cannot write '" + path + "': the image is empty");
    if (image.pixels.size() != image.sampleCount())
        throw Error("cannot write '" + path + "': pixel buffer does not match " + image.describe());
    const std::string extension = lowerExtension(path);
    const PixelType storage = storableType(extension, options.storage.value_or(image.storage));
    if ((extension == ".png") && image.channels() > 4)
        throw Error("cannot write '" + path + "': PNG holds 1 to 4 channels, the image has " +
                    std::to_string(image.channels()) + " (use .exr)");
    if ((extension == ".jpg" || extension == ".jpeg") && image.channels() != 1 && image.channels() != 3)
        throw Error("cannot write '" + path + "': JPEG holds 1 or 3 channels, the image has " +
                    std::to_string(image.channels()));

    // Colour follows the file: integer formats hold sRGB-encoded values, half and float ones linear light.
    // An image bound for a file of the other kind is converted here, at the boundary (colour channels only).
    const Image* source = &image;
    Image converted;
    if (holdsLinearLight(image.storage) != holdsLinearLight(storage)) {
        converted = image;
        if (holdsLinearLight(storage)) {
            convertSrgbToLinear(converted);
        } else {
            for (float& v : converted.pixels) v = std::isfinite(v) ? v : 0.0f;
            convertColourChannels(converted, [](float v) { return linearToSrgb(std::max(v, 0.0f)); });
        }
        source = &converted;
    }

    auto output = OIIO::ImageOutput::create(path);
    if (!output) throw Error("cannot write '" + path + "': " + oneLine(OIIO::geterror()));
    OIIO::ImageSpec spec(image.width, image.height, image.channels(), typeDescOf(storage));
    spec.channelnames = image.channelNames;
    spec.alpha_channel = image.findChannel("A");
    spec.attribute("oiio:UnassociatedAlpha", 1);
    // No time stamp (the EXR writer would add the current time): the same image gives the same bytes,
    // so datasets can be checksummed and compared.
    spec.attribute("DateTime", "");
    if (extension == ".jpg" || extension == ".jpeg")
        spec.attribute("Compression", "jpeg:" + std::to_string(options.jpegQuality));
    // Encoded into memory, where a write cannot fail, then written by one checked path (AtomicFile): the
    // codecs' own file writers do not all report a failed write (libpng returned success on a full disk,
    // libjpeg ended the process). Every format dejag writes takes OpenImageIO's I/O proxy.
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput memory(bytes);
    if (!output->supports("ioproxy") || !output->set_ioproxy(&memory))
        throw Error("cannot write '" + path +
                    "': this format cannot be encoded in memory (use .png or .exr)");
    if (!output->open(path, spec) || !output->write_image(OIIO::TypeDesc::FLOAT, source->pixels.data()) ||
        !output->close())
        throw Error("cannot write '" + path + "': " + oneLine(output->geterror()));
    AtomicFile file(path);
    file.write(bytes.data(), bytes.size());
    file.commit();
}

float srgbToLinear(float encoded) {
    return encoded <= 0.04045f ? encoded / 12.92f : std::pow((encoded + 0.055f) / 1.055f, 2.4f);
}

float linearToSrgb(float linear) {
    return encodeSrgb(linear);
}

void convertSrgbToLinear(Image& image) {
    convertColourChannels(image, srgbToLinear);
}
void convertLinearToSrgb(Image& image) {
    convertColourChannels(image, linearToSrgb);
}

std::optional<SamplePosition> findNonFinite(const Image& image) {
    if (image.storage == PixelType::UInt8 || image.storage == PixelType::UInt16) return std::nullopt;
    const int channels = image.channels();
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        if (!std::isfinite(image.pixels[i])) {
            size_t pixel = i / channels;
            return SamplePosition{int(pixel % image.width), int(pixel / image.width), int(i % channels)};
        }
    }
    return std::nullopt;
}

}  // namespace dejag
