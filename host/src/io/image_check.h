// image_check.h (internal): walks over a Radiance .hdr, PNG or JPEG file's bytes before
// stb_image decodes it (image_read.cpp), as checkExrHeader (exr_check.h) does for
// OpenEXR. stb_image allocates the whole decoded image from the header's size before it
// reads the pixel data, and decodes zeros past the end of a short file; these walks
// refuse, from the header and the file's size, an image the file's bytes cannot hold:
//   Radiance  4 bytes a pixel flat; a run-length scanline at least its 4-byte header and
//             2 bytes per run of up to 127 values of each of its 4 components (old-style
//             run markers, which stb_image does not read, count as flat pixels);
//   PNG       its IDAT chunks' bytes inflate at most 1032-fold (deflate's limit);
//   JPEG      at least 1 bit of entropy-coded data per 8x8 block of its largest component
//             (every block's DC difference has a Huffman code of 1 bit or more).
// They also refuse data on which stb_image 2.27 misbehaves (a Radiance run of length 0,
// a JPEG Huffman table of more than 256 codes, a JPEG scan that uses a Huffman or
// quantization table that no segment before it defined) and a Radiance header that
// stb_image and the format would read differently. Each returns why the file cannot be
// decoded, or "" when stb_image can be trusted with it (including the headers stb_image
// itself refuses).
#pragma once

#include <string>
#include <vector>

namespace prtbake::detail {

std::string radianceProblem(const std::vector<unsigned char>& bytes);
std::string pngProblem(const std::vector<unsigned char>& bytes);
std::string jpegProblem(const std::vector<unsigned char>& bytes);

// A count held in a double (a header's product may exceed every integer type) as digits,
// for the checks' messages.
std::string wholeNumber(double v);

}  // namespace prtbake::detail
