// PNG, JPEG, TIFF and BMP with libpng, libjpeg and libtiff (see image_codec.h).
//
// libpng and libjpeg report errors by longjmp. The functions that call setjmp keep no local with
// a destructor alive across a library call (the image and row pointers belong to the caller), so
// the jump skips no destructor; messages go into fixed buffers.
#include "rodfit/vision/image_codec.h"

#include <algorithm>
#include <cctype>
#include <csetjmp>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <jpeglib.h>
#include <png.h>
#include <tiffio.h>

#include <opencv2/imgproc.hpp>

namespace rodfit {
namespace {

bool TooLarge(long long width, long long height, int max_side_px, long long max_pixels,
              std::string* why) {
  if (width <= 0 || height <= 0) {
    *why = "the header states an empty image";
    return true;
  }
  if (width > max_side_px || height > max_side_px || width * height > max_pixels) {
    *why = "the image is " + std::to_string(width) + "x" + std::to_string(height) +
           " px, more than " + std::to_string(max_side_px) + " px a side or " +
           std::to_string(max_pixels) + " pixels (the limit)";
    return true;
  }
  return false;
}

std::uint32_t Le(const std::string& b, size_t at, int bytes) {
  std::uint32_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

void PutLe(std::string* b, std::uint32_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) b->push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

// ----------------------------------------------------------------------------------------- PNG

struct PngSource {
  const unsigned char* data;
  size_t size;
  size_t at;
  char message[256];
};

void PngError(png_structp png, png_const_charp text) {
  auto* src = static_cast<PngSource*>(png_get_error_ptr(png));
  std::snprintf(src->message, sizeof(src->message), "%s", text ? text : "PNG error");
  png_longjmp(png, 1);
}

void PngWarning(png_structp, png_const_charp) {}  // rodfit reports for itself

void PngRead(png_structp png, png_bytep out, png_size_t count) {
  auto* src = static_cast<PngSource*>(png_get_io_ptr(png));
  if (count > src->size - src->at) png_error(png, "the file is truncated");
  std::memcpy(out, src->data + src->at, count);
  src->at += count;
}

bool DecodePng(const std::string& bytes, int max_side_px, long long max_pixels, cv::Mat* image,
               std::vector<png_bytep>* rows, std::string* why) {
  PngSource src{reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), 0, {0}};
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &src, PngError, PngWarning);
  if (!png) {
    *why = "out of memory";
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    *why = "out of memory";
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    *why = std::string("PNG: ") + src.message;
    return false;
  }
  png_set_read_fn(png, &src, PngRead);
  // The size limit is rodfit's (checked below, before any pixel is allocated); libpng's own
  // default user limit (1,000,000 px a side) is above it.
  png_read_info(png, info);
  const png_uint_32 width = png_get_image_width(png, info);
  const png_uint_32 height = png_get_image_height(png, info);
  if (TooLarge(width, height, max_side_px, max_pixels, why)) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  const int color = png_get_color_type(png, info);
  const int depth = png_get_bit_depth(png, info);
  if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
  if (color == PNG_COLOR_TYPE_GRAY_ALPHA ||
      (color == PNG_COLOR_TYPE_GRAY && png_get_valid(png, info, PNG_INFO_tRNS))) {
    png_set_gray_to_rgb(png);  // grey + alpha as BGRA (as OpenCV gives it)
  }
  if (depth == 16) png_set_swap(png);  // PNG is big-endian; CV_16U is the host's order
  png_set_bgr(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  const int channels = png_get_channels(png, info);
  const int out_depth = png_get_bit_depth(png, info);
  if ((channels != 1 && channels != 3 && channels != 4) || (out_depth != 8 && out_depth != 16)) {
    png_destroy_read_struct(&png, &info, nullptr);
    *why = "PNG: unsupported channel layout";
    return false;
  }
  image->create(static_cast<int>(height), static_cast<int>(width),
                CV_MAKETYPE(out_depth == 16 ? CV_16U : CV_8U, channels));
  rows->resize(height);
  for (png_uint_32 r = 0; r < height; ++r) (*rows)[r] = image->ptr<png_byte>(static_cast<int>(r));
  png_read_image(png, rows->data());
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

void PngWrite(png_structp png, png_bytep data, png_size_t count) {
  static_cast<std::string*>(png_get_io_ptr(png))->append(reinterpret_cast<const char*>(data),
                                                         count);
}
void PngFlush(png_structp) {}

bool EncodePng(const cv::Mat& image, std::string* bytes, std::vector<png_bytep>* rows,
               std::string* why) {
  PngSource err{nullptr, 0, 0, {0}};
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &err, PngError, PngWarning);
  if (!png) {
    *why = "out of memory";
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    *why = "out of memory";
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    *why = std::string("PNG: ") + err.message;
    return false;
  }
  png_set_write_fn(png, bytes, PngWrite, PngFlush);
  const int channels = image.channels();
  const int color = channels == 1 ? PNG_COLOR_TYPE_GRAY
                    : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGB_ALPHA;
  const int depth = image.depth() == CV_16U ? 16 : 8;
  png_set_IHDR(png, info, image.cols, image.rows, depth, color, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // Level 3: most of level 6's size at a third of its time (report overlays are large).
  png_set_compression_level(png, 3);
  png_write_info(png, info);
  if (channels > 1) png_set_bgr(png);
  if (depth == 16) png_set_swap(png);
  rows->resize(image.rows);
  for (int r = 0; r < image.rows; ++r) (*rows)[r] = const_cast<png_bytep>(image.ptr<png_byte>(r));
  png_write_image(png, rows->data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

// ---------------------------------------------------------------------------------------- JPEG

struct JpegError {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

void JpegExit(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegError*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}

void JpegMessage(j_common_ptr, int) {}  // warnings (e.g. a truncated scan) are not printed

bool DecodeJpeg(const std::string& bytes, int max_side_px, long long max_pixels, cv::Mat* image,
                std::string* why) {
  jpeg_decompress_struct cinfo;
  JpegError err;
  err.message[0] = 0;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = JpegExit;
  err.mgr.emit_message = JpegMessage;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    *why = std::string("JPEG: ") + err.message;
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, reinterpret_cast<const unsigned char*>(bytes.data()),
               static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&cinfo, TRUE);
  if (TooLarge(cinfo.image_width, cinfo.image_height, max_side_px, max_pixels, why)) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  const bool cmyk = cinfo.num_components == 4;
  int channels = 3;
  if (cinfo.num_components == 1) {
    cinfo.out_color_space = JCS_GRAYSCALE;
    channels = 1;
  } else if (cmyk) {
    cinfo.out_color_space = JCS_CMYK;
    channels = 4;
  } else {
    cinfo.out_color_space = JCS_EXT_BGR;
  }
  jpeg_start_decompress(&cinfo);
  if (static_cast<int>(cinfo.output_components) != channels) {
    jpeg_destroy_decompress(&cinfo);
    *why = "JPEG: unsupported colour space";
    return false;
  }
  image->create(static_cast<int>(cinfo.output_height), static_cast<int>(cinfo.output_width),
                CV_8UC(channels));
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = image->ptr<JSAMPLE>(static_cast<int>(cinfo.output_scanline));
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  const bool adobe_inverted = cinfo.saw_Adobe_marker;
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  if (cmyk) {
    // CMYK (or YCCK decoded to CMYK) to BGR; Adobe's files store the inks inverted.
    cv::Mat bgr(image->rows, image->cols, CV_8UC3);
    for (int r = 0; r < image->rows; ++r) {
      const unsigned char* in = image->ptr<unsigned char>(r);
      unsigned char* out = bgr.ptr<unsigned char>(r);
      for (int c = 0; c < image->cols; ++c, in += 4, out += 3) {
        const int k = adobe_inverted ? in[3] : 255 - in[3];
        auto ink = [&](int v) { return (adobe_inverted ? v : 255 - v) * k / 255; };
        out[0] = static_cast<unsigned char>(ink(in[2]));
        out[1] = static_cast<unsigned char>(ink(in[1]));
        out[2] = static_cast<unsigned char>(ink(in[0]));
      }
    }
    *image = bgr;
  }
  return true;
}

bool EncodeJpeg(const cv::Mat& input, int quality, std::string* bytes, std::string* why) {
  cv::Mat image;
  if (input.channels() == 4) {
    cv::cvtColor(input, image, cv::COLOR_BGRA2BGR);
  } else {
    image = input;
  }
  jpeg_compress_struct cinfo;
  JpegError err;
  err.message[0] = 0;
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = JpegExit;
  err.mgr.emit_message = JpegMessage;
  if (setjmp(err.jump)) {
    jpeg_destroy_compress(&cinfo);
    std::free(buffer);
    *why = std::string("JPEG: ") + err.message;
    return false;
  }
  jpeg_create_compress(&cinfo);
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = static_cast<JDIMENSION>(image.cols);
  cinfo.image_height = static_cast<JDIMENSION>(image.rows);
  cinfo.input_components = image.channels();
  cinfo.in_color_space = image.channels() == 1 ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, std::clamp(quality, 1, 100), TRUE);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row = const_cast<JSAMPROW>(image.ptr<JSAMPLE>(static_cast<int>(cinfo.next_scanline)));
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  bytes->assign(reinterpret_cast<const char*>(buffer), size);
  jpeg_destroy_compress(&cinfo);
  std::free(buffer);
  return true;
}

// ---------------------------------------------------------------------------------------- TIFF

// A TIFF file in memory: libtiff reads and writes it through these client procedures.
struct TiffMemory {
  std::string* data;  // written file (encode) or nullptr
  const char* in;     // file read (decode)
  size_t size;
  size_t at;
  char message[256];
};

tmsize_t TiffRead(thandle_t h, void* out, tmsize_t n) {
  auto* m = static_cast<TiffMemory*>(h);
  if (n < 0 || m->at > m->size) return 0;
  const size_t count = std::min(static_cast<size_t>(n), m->size - m->at);
  std::memcpy(out, m->in + m->at, count);
  m->at += count;
  return static_cast<tmsize_t>(count);
}

tmsize_t TiffWrite(thandle_t h, void* from, tmsize_t n) {
  auto* m = static_cast<TiffMemory*>(h);
  if (!m->data || n < 0) return 0;
  if (m->at + n > m->data->size()) m->data->resize(m->at + n);
  std::memcpy(&(*m->data)[m->at], from, static_cast<size_t>(n));
  m->at += n;
  m->size = m->data->size();
  m->in = m->data->data();
  return n;
}

toff_t TiffSeek(thandle_t h, toff_t offset, int whence) {
  auto* m = static_cast<TiffMemory*>(h);
  const long long base = whence == SEEK_CUR ? static_cast<long long>(m->at)
                         : whence == SEEK_END ? static_cast<long long>(m->size) : 0;
  const long long to = base + static_cast<long long>(offset);
  if (to < 0) return static_cast<toff_t>(-1);
  m->at = static_cast<size_t>(to);
  return static_cast<toff_t>(to);
}

int TiffClose(thandle_t) { return 0; }
toff_t TiffSize(thandle_t h) { return static_cast<TiffMemory*>(h)->size; }
int TiffMap(thandle_t, void**, toff_t*) { return 0; }
void TiffUnmap(thandle_t, void*, toff_t) {}

int TiffError(TIFF*, void* user, const char*, const char* format, va_list args) {
  auto* m = static_cast<TiffMemory*>(user);
  if (!m->message[0]) std::vsnprintf(m->message, sizeof(m->message), format, args);
  return 1;  // handled: libtiff prints nothing
}

int TiffWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

TIFF* TiffOpen(TiffMemory* m, const char* mode) {
  TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
  TIFFOpenOptionsSetErrorHandlerExtR(options, TiffError, m);
  TIFFOpenOptionsSetWarningHandlerExtR(options, TiffWarning, m);
  TIFF* tif = TIFFClientOpenExt("memory", mode, m, TiffRead, TiffWrite, TiffSeek, TiffClose,
                                TiffSize, TiffMap, TiffUnmap, options);
  TIFFOpenOptionsFree(options);
  return tif;
}

std::string TiffWhy(const TiffMemory& m, const char* fallback) {
  return std::string("TIFF: ") + (m.message[0] ? m.message : fallback);
}

bool DecodeTiff(const std::string& bytes, int max_side_px, long long max_pixels, cv::Mat* image,
                std::string* why) {
  TiffMemory m{nullptr, bytes.data(), bytes.size(), 0, {0}};
  TIFF* tif = TiffOpen(&m, "rm");
  if (!tif) {
    *why = TiffWhy(m, "not a TIFF file");
    return false;
  }
  std::uint32_t width = 0, height = 0;
  std::uint16_t spp = 1, bps = 1, planar = PLANARCONFIG_CONTIG, photometric = PHOTOMETRIC_RGB;
  std::uint16_t format = SAMPLEFORMAT_UINT;
  TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &width);
  TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &height);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
  TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bps);
  TIFFGetFieldDefaulted(tif, TIFFTAG_PLANARCONFIG, &planar);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &format);
  if (!TIFFGetField(tif, TIFFTAG_PHOTOMETRIC, &photometric)) photometric = PHOTOMETRIC_MINISBLACK;
  if (TooLarge(width, height, max_side_px, max_pixels, why)) {
    TIFFClose(tif);
    return false;
  }
  const bool plain = !TIFFIsTiled(tif) && planar == PLANARCONFIG_CONTIG &&
                     format == SAMPLEFORMAT_UINT && (bps == 8 || bps == 16) &&
                     ((spp == 1 && (photometric == PHOTOMETRIC_MINISBLACK ||
                                    photometric == PHOTOMETRIC_MINISWHITE)) ||
                      ((spp == 3 || spp == 4) && photometric == PHOTOMETRIC_RGB));
  if (plain) {
    // Strips of 8- or 16-bit grey, RGB or RGBA samples: read as stored (16 bits kept).
    const int depth = bps == 16 ? CV_16U : CV_8U;
    image->create(static_cast<int>(height), static_cast<int>(width), CV_MAKETYPE(depth, spp));
    if (TIFFScanlineSize(tif) != static_cast<tmsize_t>(image->cols * image->elemSize())) {
      TIFFClose(tif);
      *why = "TIFF: unexpected scanline size";
      return false;
    }
    for (std::uint32_t r = 0; r < height; ++r) {
      if (TIFFReadScanline(tif, image->ptr(static_cast<int>(r)), r, 0) < 0) {
        TIFFClose(tif);
        *why = TiffWhy(m, "cannot read the pixels");
        return false;
      }
    }
    TIFFClose(tif);
    if (photometric == PHOTOMETRIC_MINISWHITE) cv::bitwise_not(*image, *image);
    if (spp == 3) cv::cvtColor(*image, *image, cv::COLOR_RGB2BGR);
    if (spp == 4) cv::cvtColor(*image, *image, cv::COLOR_RGBA2BGRA);
    return true;
  }
  // Anything else libtiff can render (palette, YCbCr, tiles, bit depths below 8, separate
  // planes): 8-bit RGBA, then BGR, or BGRA when the file has an alpha sample.
  char message[1024] = {0};
  if (!TIFFRGBAImageOK(tif, message)) {
    TIFFClose(tif);
    *why = std::string("TIFF: unsupported variant: ") + message;
    return false;
  }
  cv::Mat rgba(static_cast<int>(height), static_cast<int>(width), CV_8UC4);
  if (!TIFFReadRGBAImageOriented(tif, width, height, rgba.ptr<std::uint32_t>(), ORIENTATION_TOPLEFT,
                                 0)) {
    TIFFClose(tif);
    *why = TiffWhy(m, "cannot read the pixels");
    return false;
  }
  TIFFClose(tif);
  // Each pixel is a uint32 A<<24 | B<<16 | G<<8 | R: bytes R, G, B, A in memory (little-endian).
  const bool alpha = spp == 2 || spp == 4;
  cv::cvtColor(rgba, *image, alpha ? cv::COLOR_RGBA2BGRA : cv::COLOR_RGBA2BGR);
  return true;
}

bool EncodeTiff(const cv::Mat& input, std::string* bytes, std::string* why) {
  // A new matrix for the swapped channels (never converted in place: `input` is the caller's).
  const int channels = input.channels();
  cv::Mat image;
  if (channels == 1) image = input;
  if (channels == 3) cv::cvtColor(input, image, cv::COLOR_BGR2RGB);
  if (channels == 4) cv::cvtColor(input, image, cv::COLOR_BGRA2RGBA);
  bytes->clear();
  TiffMemory m{bytes, bytes->data(), 0, 0, {0}};
  TIFF* tif = TiffOpen(&m, "w");
  if (!tif) {
    *why = TiffWhy(m, "cannot start the file");
    return false;
  }
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, static_cast<std::uint32_t>(image.cols));
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, static_cast<std::uint32_t>(image.rows));
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, static_cast<std::uint16_t>(channels));
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, static_cast<std::uint16_t>(image.depth() == CV_16U ? 16 : 8));
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, channels == 1 ? PHOTOMETRIC_MINISBLACK : PHOTOMETRIC_RGB);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
  if (channels == 4) {
    const std::uint16_t extra = EXTRASAMPLE_UNASSALPHA;
    TIFFSetField(tif, TIFFTAG_EXTRASAMPLES, 1, &extra);
  }
  TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, TIFFDefaultStripSize(tif, 0));
  for (int r = 0; r < image.rows; ++r) {
    if (TIFFWriteScanline(tif, const_cast<unsigned char*>(image.ptr(r)), static_cast<std::uint32_t>(r), 0) < 0) {
      TIFFClose(tif);
      *why = TiffWhy(m, "cannot write the pixels");
      return false;
    }
  }
  TIFFClose(tif);  // writes the directory
  if (m.message[0]) {
    *why = TiffWhy(m, "");
    return false;
  }
  return true;
}

// ----------------------------------------------------------------------------------------- BMP

bool DecodeBmp(const std::string& b, int max_side_px, long long max_pixels, cv::Mat* image,
               std::string* why) {
  if (b.size() < 54) {
    *why = "BMP: the header is truncated";
    return false;
  }
  const std::uint32_t offset = Le(b, 10, 4);
  const std::uint32_t dib = Le(b, 14, 4);
  const std::int32_t w = static_cast<std::int32_t>(Le(b, 18, 4));
  const std::int32_t h = static_cast<std::int32_t>(Le(b, 22, 4));
  const int bpp = static_cast<int>(Le(b, 28, 2));
  const std::uint32_t compression = Le(b, 30, 4);
  if (dib < 40 || 14ull + dib > b.size()) {
    *why = "BMP: unsupported header (OS/2 or truncated)";
    return false;
  }
  const long long width = w, height = h < 0 ? -static_cast<long long>(h) : h;
  if (TooLarge(width, height, max_side_px, max_pixels, why)) return false;
  // BI_RGB, or BI_BITFIELDS with the usual 32-bit masks (B, G, R in the low three bytes).
  const bool bitfields_bgr = compression == 3 && bpp == 32 && dib >= 52 &&
                             Le(b, 54, 4) == 0x00FF0000u && Le(b, 58, 4) == 0x0000FF00u &&
                             Le(b, 62, 4) == 0x000000FFu;
  if (!(compression == 0 || bitfields_bgr) || (bpp != 8 && bpp != 24 && bpp != 32)) {
    *why = "BMP: only uncompressed 8-, 24- and 32-bit images are read";
    return false;
  }
  const size_t stride = ((static_cast<size_t>(width) * bpp + 31) / 32) * 4;
  if (offset > b.size() || stride * static_cast<size_t>(height) > b.size() - offset) {
    *why = "BMP: the file is truncated";
    return false;
  }
  std::vector<unsigned char> palette_bgr;
  bool grey_palette = true;
  if (bpp == 8) {
    std::uint32_t colours = Le(b, 46, 4);
    if (colours == 0 || colours > 256) colours = 256;
    const size_t at = 14 + dib;
    if (at + 4ull * colours > offset) {
      *why = "BMP: the palette is truncated";
      return false;
    }
    palette_bgr.assign(3 * 256, 0);
    for (std::uint32_t k = 0; k < colours; ++k) {
      for (int c = 0; c < 3; ++c) palette_bgr[3 * k + c] = static_cast<unsigned char>(b[at + 4 * k + c]);
      grey_palette = grey_palette && palette_bgr[3 * k] == palette_bgr[3 * k + 1] &&
                     palette_bgr[3 * k] == palette_bgr[3 * k + 2];
    }
  }
  const int channels = (bpp == 8 && grey_palette) ? 1 : 3;
  image->create(static_cast<int>(height), static_cast<int>(width), CV_8UC(channels));
  for (long long r = 0; r < height; ++r) {
    const long long stored = h < 0 ? r : height - 1 - r;  // bottom-up unless height < 0
    const auto* in = reinterpret_cast<const unsigned char*>(b.data() + offset + stored * stride);
    unsigned char* out = image->ptr<unsigned char>(static_cast<int>(r));
    for (long long c = 0; c < width; ++c) {
      if (bpp == 8) {
        const unsigned char* p = &palette_bgr[3 * in[c]];
        if (channels == 1) {
          out[c] = p[0];
        } else {
          std::memcpy(out + 3 * c, p, 3);
        }
      } else {
        std::memcpy(out + 3 * c, in + (bpp / 8) * c, 3);  // B, G, R (a 32-bit pixel's 4th byte unused)
      }
    }
  }
  return true;
}

bool EncodeBmp(const cv::Mat& image, std::string* bytes, std::string* why) {
  if (image.depth() != CV_8U) {
    *why = "BMP holds 8-bit samples only";
    return false;
  }
  const int channels = image.channels();
  const int bpp = channels == 1 ? 8 : 24;
  const size_t stride = ((static_cast<size_t>(image.cols) * bpp + 31) / 32) * 4;
  const std::uint32_t palette = channels == 1 ? 256 * 4 : 0;
  const std::uint32_t offset = 54 + palette;
  bytes->clear();
  bytes->reserve(offset + stride * image.rows);
  bytes->append("BM");
  PutLe(bytes, static_cast<std::uint32_t>(offset + stride * image.rows), 4);
  PutLe(bytes, 0, 4);
  PutLe(bytes, offset, 4);
  PutLe(bytes, 40, 4);
  PutLe(bytes, static_cast<std::uint32_t>(image.cols), 4);
  PutLe(bytes, static_cast<std::uint32_t>(image.rows), 4);  // bottom-up
  PutLe(bytes, 1, 2);
  PutLe(bytes, static_cast<std::uint32_t>(bpp), 2);
  PutLe(bytes, 0, 4);  // BI_RGB
  PutLe(bytes, static_cast<std::uint32_t>(stride * image.rows), 4);
  PutLe(bytes, 2835, 4);  // 72 dpi
  PutLe(bytes, 2835, 4);
  PutLe(bytes, channels == 1 ? 256 : 0, 4);
  PutLe(bytes, 0, 4);
  for (std::uint32_t k = 0; k < palette / 4; ++k) {
    for (int c = 0; c < 3; ++c) bytes->push_back(static_cast<char>(k));
    bytes->push_back(0);
  }
  std::vector<char> row(stride, 0);
  for (int r = image.rows - 1; r >= 0; --r) {
    const unsigned char* in = image.ptr<unsigned char>(r);
    for (int c = 0; c < image.cols; ++c) {
      if (channels == 1) {
        row[c] = static_cast<char>(in[c]);
      } else {
        std::memcpy(&row[3 * c], in + channels * c, 3);  // BGRA's alpha dropped
      }
    }
    bytes->append(row.data(), row.size());
  }
  return true;
}

}  // namespace

ImageFormat SniffImageFormat(const std::string& b) {
  if (b.size() >= 8 && b.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) return ImageFormat::kPng;
  if (b.size() >= 3 && static_cast<unsigned char>(b[0]) == 0xFF &&
      static_cast<unsigned char>(b[1]) == 0xD8 && static_cast<unsigned char>(b[2]) == 0xFF)
    return ImageFormat::kJpeg;
  if (b.size() >= 4 && (b.compare(0, 4, std::string("II*\0", 4)) == 0 ||
                        b.compare(0, 4, std::string("MM\0*", 4)) == 0 ||
                        b.compare(0, 4, std::string("II+\0", 4)) == 0 ||
                        b.compare(0, 4, std::string("MM\0+", 4)) == 0))
    return ImageFormat::kTiff;
  if (b.size() >= 2 && b.compare(0, 2, "BM") == 0) return ImageFormat::kBmp;
  return ImageFormat::kUnknown;
}

ImageFormat ImageFormatFromExtension(const std::string& extension) {
  std::string e = extension;
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  if (e == ".png") return ImageFormat::kPng;
  if (e == ".jpg" || e == ".jpeg") return ImageFormat::kJpeg;
  if (e == ".tif" || e == ".tiff") return ImageFormat::kTiff;
  if (e == ".bmp") return ImageFormat::kBmp;
  return ImageFormat::kUnknown;
}

bool DecodeImageBytes(const std::string& bytes, int max_side_px, long long max_pixels,
                      cv::Mat* image, std::string* why) {
  image->release();
  std::vector<png_bytep> rows;
  bool ok = false;
  switch (SniffImageFormat(bytes)) {
    case ImageFormat::kPng: ok = DecodePng(bytes, max_side_px, max_pixels, image, &rows, why); break;
    case ImageFormat::kJpeg: ok = DecodeJpeg(bytes, max_side_px, max_pixels, image, why); break;
    case ImageFormat::kTiff: ok = DecodeTiff(bytes, max_side_px, max_pixels, image, why); break;
    case ImageFormat::kBmp: ok = DecodeBmp(bytes, max_side_px, max_pixels, image, why); break;
    case ImageFormat::kUnknown:
      *why = "not a PNG, JPEG, TIFF or BMP image";
      break;
  }
  if (!ok) image->release();
  return ok;
}

bool EncodeImageBytes(ImageFormat format, const cv::Mat& image, std::string* bytes,
                      std::string* why, int jpeg_quality) {
  bytes->clear();
  const int channels = image.channels();
  if (image.empty() || (channels != 1 && channels != 3 && channels != 4) ||
      (image.depth() != CV_8U && image.depth() != CV_16U)) {
    *why = "only non-empty 8- or 16-bit images of 1, 3 or 4 channels are written";
    return false;
  }
  const cv::Mat contiguous = image.isContinuous() ? image : image.clone();
  std::vector<png_bytep> rows;
  bool ok = false;
  switch (format) {
    case ImageFormat::kPng: ok = EncodePng(contiguous, bytes, &rows, why); break;
    case ImageFormat::kTiff: ok = EncodeTiff(contiguous, bytes, why); break;
    case ImageFormat::kJpeg:
    case ImageFormat::kBmp:
      if (image.depth() != CV_8U) {
        *why = "JPEG and BMP hold 8-bit samples only";
        break;
      }
      ok = format == ImageFormat::kJpeg ? EncodeJpeg(contiguous, jpeg_quality, bytes, why)
                                        : EncodeBmp(contiguous, bytes, why);
      break;
    case ImageFormat::kUnknown:
      *why = "unknown image format (use .png, .jpg, .tif or .bmp)";
      break;
  }
  if (!ok) bytes->clear();
  return ok;
}

}  // namespace rodfit
