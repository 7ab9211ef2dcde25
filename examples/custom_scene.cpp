// A scene built in code (a mirror floor under a coloured box), rendered with one-bounce
// reflections by two tracers: HSSR through the captured k layers, and Embree.
#include <cstdio>
#include <string>

#include <layertrace/layertrace.h>

int main(int argc, char** argv) {
  const std::string out = argc > 1 ? argv[1] : ".";
  std::vector<glm::vec3> positions = {{-5, 0, -5}, {-5, 0, 5}, {5, 0, 5}, {5, 0, -5},  // floor
                                      {-1, 0, -1}, {1, 0, -1}, {1, 2, -1}, {-1, 2, -1},  // box front
                                      {-1, 0, -3}, {-1, 0, -1}, {-1, 2, -1}, {-1, 2, -3}};  // box side
  std::vector<glm::uvec3> triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}, {8, 9, 10}, {8, 10, 11}};
  std::vector<uint32_t> material = {0, 0, 1, 1, 2, 2};
  std::vector<lt::MeshMaterial> materials = {{{0.3f, 0.3f, 0.3f}, 0.8f}, {{0.9f, 0.2f, 0.1f}, 0.0f}, {{0.1f, 0.4f, 0.9f}, 0.0f}};
  const lt::TriangleScene scene(positions, triangles, material, materials);

  lt::RenderRequest request;
  request.view.eye = {3.0f, 2.5f, 5.0f};
  request.view.target = {0.0f, 0.5f, -1.0f};
  request.view.width = 320, request.view.height = 180;
  request.view.near = 0.05f, request.view.far = 50.0f;
  for (const char* tracer : {"hssr", "embree"}) {
    request.tracer = tracer;
    const lt::RgbImage image = lt::render(scene, request);
    double sum = 0.0;
    for (float v : image.rgb) sum += v;
    std::printf("custom_scene: %s, mean value %.4f\n", tracer, sum / double(image.rgb.size()));
    image.savePng(out + "/custom_scene_" + tracer + ".png");
  }
  return 0;
}
