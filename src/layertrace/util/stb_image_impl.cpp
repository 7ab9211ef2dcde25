// The implementation of stb_image and stb_image_write (Debian's libstb-dev), in a file of its own
// so that the sanitizer build can spare it one check (CMakeLists.txt): stb_image calls
// memcpy(nullptr, p, 0) on some malformed PNGs (stbi__getn with an empty read), which the
// nonnull-attribute check of UBSan reports although no byte is copied. AddressSanitizer and every
// other check still cover it; the texture fuzzer feeds it malformed images.
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#define STBI_ONLY_JPEG  // model textures (decodeRgba8)
#define STBI_ONLY_TGA
#define STBI_ONLY_BMP
#include <stb_image.h>
#include <stb_image_write.h>
