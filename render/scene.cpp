#include "render/scene.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "base/error.h"
#include "base/random.h"
#include "render/vector_art.h"

namespace dejag::render {

namespace {

// SplitMix64: a tiny deterministic generator (the same scenes on every machine and compiler).
class Random {
  public:
    explicit Random(uint64_t seed) : state_(seed * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull) {}
    uint64_t next() {
        const uint64_t r = splitMix64(state_);  // counter-based: the state steps by the increment
        state_ += 0x9E3779B97F4A7C15ull;
        return r;
    }
    double uniform(double low = 0.0, double high = 1.0) { return unitInterval(next(), low, high); }
    int below(int n) { return int(next() % uint64_t(n)); }
    Vec3 unitVector() {
        const double z = uniform(-1, 1), a = uniform(0, 2 * kPi), r = std::sqrt(1 - z * z);
        return {r * std::cos(a), r * std::sin(a), z};
    }
    Vec3 colour() { return {uniform(0.1, 0.9), uniform(0.1, 0.9), uniform(0.1, 0.9)}; }

  private:
    uint64_t state_;
};

Material solid(const Vec3& colour, bool lit = true, double specular = 0.0) {
    Material m;
    m.colour = colour, m.lit = lit, m.specular = specular;
    return m;
}

std::function<CameraPose(double)> fixedCamera(const Vec3& eye, const Vec3& target, double fovDegrees = 45.0,
                                              const Vec3& up = {0, 1, 0}) {
    return [=](double) { return CameraPose{eye, target, up, fovDegrees * kPi / 180.0}; };
}

// The tilted variant of a camera: turned 12 degrees about the vertical and rolled 17 degrees, so the
// scene's horizontal and vertical edges reach the image at angles where aliasing steps are irregular.
std::function<CameraPose(double)> tilt(std::function<CameraPose(double)> camera) {
    return [camera](double t) {
        CameraPose pose = camera(t);
        const Vec3 forward = pose.target - pose.eye;
        pose.target = pose.eye + Mat4::rotation({0, 1, 0}, 12.0 * kPi / 180.0).transformDirection(forward);
        pose.up =
            Mat4::rotation(normalize(pose.target - pose.eye), 17.0 * kPi / 180.0).transformDirection(pose.up);
        return pose;
    };
}

Mesh floorMesh(double size) {
    Mesh floor;
    floor.append(makeQuad(size, size, size / 2, size / 2), Mat4::rotation({1, 0, 0}, -kPi / 2));
    return floor;
}

// A circular arc in the XY plane from angle a0 to a1 (radians), as a polyline.
std::vector<Vec3> arc(const Vec3& centre, double radius, double a0, double a1, int segments) {
    std::vector<Vec3> points;
    for (int i = 0; i <= segments; ++i) {
        const double a = a0 + (a1 - a0) * i / segments;
        points.push_back(centre + Vec3{radius * std::cos(a), radius * std::sin(a), 0});
    }
    return points;
}

// ---- Scenes ------------------------------------------------------------------------------------------

void sphereScene(Scene& s, const SceneOptions&) {
    s.addObject("floor", s.addMesh(floorMesh(40)), solid({0.45, 0.45, 0.42}));
    s.addObject("sphere", s.addMesh(makeSphere(1.0, 96, 48)), solid({0.8, 0.15, 0.1}, true, 0.3), [](double) {
        return Mat4::translation({0, 1, 0});
    });
    s.camera = fixedCamera({0, 2.2, 6}, {0, 0.9, 0});
}

void corridorScene(Scene& s, const SceneOptions&) {
    // A corridor along -z; the camera looks down it while a sphere comes towards it, weaving sideways.
    const int wall = s.addMesh(makeBox({0.2, 3, 40}));
    s.addObject("floor", s.addMesh(makeBox({4.4, 0.2, 40})), solid({0.4, 0.4, 0.38}), [](double) {
        return Mat4::translation({0, -0.1, -12});
    });
    s.addObject("ceiling", s.addMesh(makeBox({4.4, 0.2, 40})), solid({0.85, 0.85, 0.82}), [](double) {
        return Mat4::translation({0, 3.1, -12});
    });
    s.addObject("left wall", wall, solid({0.7, 0.65, 0.55}), [](double) {
        return Mat4::translation({-2.1, 1.5, -12});
    });
    s.addObject("right wall", wall, solid({0.55, 0.6, 0.7}), [](double) {
        return Mat4::translation({2.1, 1.5, -12});
    });
    // Door frames along both walls give the moving sphere edges to ghost over.
    const int frame = s.addMesh(makeBox({0.1, 2.4, 0.15}));
    for (int i = 0; i < 12; ++i)
        for (const double x : {-1.98, 1.98})
            s.addObject("door frame", frame, solid({0.15, 0.12, 0.1}), [i, x](double) {
                return Mat4::translation({x, 1.2, 2.0 - 2.5 * i});
            });
    s.addObject("sphere", s.addMesh(makeSphere(0.5, 64, 32)), solid({0.9, 0.8, 0.1}, true, 0.4),
                [](double t) {
                    return Mat4::translation({1.2 * std::sin(0.09 * t), 0.6, -14.0 + 0.12 * t});
                });
    s.camera = fixedCamera({0, 1.5, 4.5}, {0, 1.1, -10}, 55);
}

void textWallScene(Scene& s, const SceneOptions& o) {
    s.textures.push_back(makeTexture("text", 1024, o.seed));
    Material m = solid({1, 1, 1}, false);
    m.pattern = Pattern::Texture, m.texture = 0;
    s.addObject("wall", s.addMesh(makeQuad(6, 6)), m);
    s.camera = fixedCamera({0.8, 0.3, 6.5}, {0, 0, 0}, 50);
}

void pipeScene(Scene& s, const SceneOptions&) {
    // A bent pipe: up, a quarter bend, across, a bend, and down towards the viewer.
    std::vector<Vec3> path = {{-3, 0, 0}, {-3, 1.5, 0}};
    for (const Vec3& p : arc({-2, 1.5, 0}, 1.0, kPi, kPi / 2, 16)) path.push_back(p);
    path.push_back({1.5, 2.5, 0});
    for (const Vec3& p : arc({1.5, 1.5, 0}, 1.0, kPi / 2, 0, 16)) path.push_back(p);
    path.push_back({2.5, 0, 0});
    s.addObject("pipe", s.addMesh(makeTube(path, 0.3, 32)), solid({0.45, 0.26, 0.12}, true, 0.2));
    s.addObject("wall", s.addMesh(makeQuad(20, 10)), solid({0.82, 0.8, 0.75}), [](double) {
        return Mat4::translation({0, 2, -1.5});
    });
    s.camera = fixedCamera({0, 1.6, 7}, {0, 1.3, 0});
}

void blindsScene(Scene& s, const SceneOptions&) {
    // Closed blinds: slats 0.08 high every 0.0852, so the gaps are about a pixel wide at 800x800.
    s.background = {1.0, 0.98, 0.9};  // daylight behind
    const int slat = s.addMesh(makeBox({2.4, 0.08, 0.01}));
    for (int i = 0; i < 36; ++i)
        s.addObject("slat", slat, solid({0.42, 0.45, 0.5}, false), [i](double) {
            return Mat4::translation({0, -1.5 + 0.0852 * i, 0});
        });
    const int side = s.addMesh(makeBox({0.12, 3.4, 0.12})), top = s.addMesh(makeBox({2.64, 0.12, 0.12}));
    const Material frame = solid({0.35, 0.22, 0.12}, false);
    s.addObject("frame", side, frame, [](double) { return Mat4::translation({-1.26, 0, 0.05}); });
    s.addObject("frame", side, frame, [](double) { return Mat4::translation({1.26, 0, 0.05}); });
    s.addObject("frame", top, frame, [](double) { return Mat4::translation({0, 1.64, 0.05}); });
    s.addObject("frame", top, frame, [](double) { return Mat4::translation({0, -1.64, 0.05}); });
    // The wall around the window: four pieces leaving the opening.
    const Material wall = solid({0.7, 0.68, 0.62}, false);
    const int piece = s.addMesh(makeQuad(8.7, 12));
    s.addObject("wall", piece, wall, [](double) { return Mat4::translation({-1.32 - 4.35, 0, -0.02}); });
    s.addObject("wall", piece, wall, [](double) { return Mat4::translation({1.32 + 4.35, 0, -0.02}); });
    const int band = s.addMesh(makeQuad(2.64, 5));
    s.addObject("wall", band, wall, [](double) { return Mat4::translation({0, 1.7 + 2.5, -0.02}); });
    s.addObject("wall", band, wall, [](double) { return Mat4::translation({0, -1.7 - 2.5, -0.02}); });
    s.camera = fixedCamera({0.3, 0.1, 4.2}, {0, 0, 0}, 48);
}

void archedWindowScene(Scene& s, const SceneOptions&) {
    s.background = {0.62, 0.78, 0.95};  // sky through the window
    const Material frame = solid({0.3, 0.22, 0.16}, false), bar = solid({0.12, 0.12, 0.14}, false);
    // The arch: an outer semicircle, an inner one and radial glazing bars, on two jambs and a sill.
    Mesh arch;
    arch.append(makeTube(arc({0, 1, 0}, 1.2, 0, kPi, 64), 0.06, 12));
    arch.append(makeTube(arc({0, 1, 0}, 0.6, 0, kPi, 48), 0.02, 8));
    for (int i = 1; i < 8; ++i) {
        const double a = kPi * i / 8;
        arch.append(makeTube(
            {{0.6 * std::cos(a), 1 + 0.6 * std::sin(a), 0}, {1.2 * std::cos(a), 1 + 1.2 * std::sin(a), 0}},
            0.012, 6));
    }
    s.addObject("arch", s.addMesh(std::move(arch)), frame);
    const int jamb = s.addMesh(makeBox({0.12, 2.4, 0.12}));
    s.addObject("jamb", jamb, frame, [](double) { return Mat4::translation({-1.2, -0.2, 0}); });
    s.addObject("jamb", jamb, frame, [](double) { return Mat4::translation({1.2, -0.2, 0}); });
    s.addObject("sill", s.addMesh(makeBox({2.6, 0.1, 0.3})), frame, [](double) {
        return Mat4::translation({0, -1.4, 0.05});
    });
    const int mullion = s.addMesh(makeBox({0.025, 2.4, 0.025})),
              transom = s.addMesh(makeBox({2.4, 0.025, 0.025}));
    for (int i = -2; i <= 2; ++i)
        s.addObject("mullion", mullion, bar, [i](double) { return Mat4::translation({0.4 * i, -0.2, 0}); });
    for (int i = 0; i < 5; ++i)
        s.addObject("transom", transom, bar, [i](double) {
            return Mat4::translation({0, -1.3 + 0.5 * i, 0});
        });
    s.camera = fixedCamera({0.4, 0.2, 4.0}, {0, 0.1, 0}, 55);
}

Mesh hairballMesh(uint64_t seed, int strands) {
    Random random(seed ^ 0x4A41ull);
    Mesh hair;
    for (int i = 0; i < strands; ++i) {
        // A curved strand: a random walk with momentum, kept inside the unit ball.
        Vec3 p = random.unitVector() * std::cbrt(random.uniform()) * 0.9, d = random.unitVector();
        std::vector<Vec3> path{p};
        for (int k = 0; k < 14; ++k) {
            d = normalize(d + random.unitVector() * 0.45 - p * 0.35);
            p = p + d * 0.09;
            path.push_back(p);
        }
        hair.append(makeTube(path, 0.0035, 4));
    }
    return hair;
}

void hairballScene(Scene& s, const SceneOptions& o, bool lit, bool rotating) {
    s.background = {0.9, 0.9, 0.9};
    Material m = solid({0.12, 0.1, 0.35}, lit, lit ? 0.5 : 0.0);
    m.shininess = 60;
    s.addObject("hairball", s.addMesh(hairballMesh(o.seed, 2500)), m, [rotating](double t) {
        return rotating ? Mat4::rotation({0.2, 1, 0.1}, 1.2 * kPi / 180.0 * t) : Mat4();
    });
    s.camera = fixedCamera({0, 0, 2.6}, {0, 0, 0}, 50);
}

void atriumScene(Scene& s, const SceneOptions&) {
    s.addObject("floor", s.addMesh(floorMesh(60)), solid({0.6, 0.55, 0.48}));
    const int column = s.addMesh(makeTube({{0, 0, 0}, {0, 3, 0}}, 0.18, 24));
    const int archMesh = s.addMesh(makeTube(arc({0, 0, 0}, 0.9, 0, kPi, 32), 0.12, 12));
    const Material stone = solid({0.85, 0.8, 0.7}, true, 0.05);
    // Two storeys of arcades around a square courtyard.
    for (int side = 0; side < 4; ++side)
        for (int i = -3; i <= 3; ++i)
            for (int storey = 0; storey < 2; ++storey) {
                const double angle = side * kPi / 2, y = storey * 3.9;
                const Mat4 place = Mat4::rotation({0, 1, 0}, angle) * Mat4::translation({i * 1.8, y, -6.3});
                s.addObject("column", column, stone, [place](double) { return place; });
                if (i < 3)
                    s.addObject("arch", archMesh, stone, [place](double) {
                        return place * Mat4::translation({0.9, 3.0, 0});
                    });
            }
    const int beam = s.addMesh(makeBox({12.6, 0.25, 0.5}));
    for (int side = 0; side < 4; ++side)
        for (int storey = 0; storey < 2; ++storey) {
            const Mat4 place = Mat4::rotation({0, 1, 0}, side * kPi / 2) *
                               Mat4::translation({0, 3.9 + storey * 3.9 + 0.12, -6.3});
            s.addObject("entablature", beam, stone, [place](double) { return place; });
        }
    s.addObject("sphere", s.addMesh(makeSphere(0.8, 64, 32)), solid({0.7, 0.2, 0.15}, true, 0.4), [](double) {
        return Mat4::translation({0, 0.8, 0});
    });
    s.camera = fixedCamera({1.5, 1.7, 5.2}, {-0.5, 2.2, -6}, 60);
}

void flowersScene(Scene& s, const SceneOptions& o) {
    s.textures.push_back(makeTexture("flower", 256, o.seed));
    s.addObject("ground", s.addMesh(floorMesh(30)), solid({0.3, 0.25, 0.15}));
    Random random(o.seed ^ 0xF10ull);
    Mesh stems, heads;
    for (int i = 0; i < 160; ++i) {
        const Vec3 base{random.uniform(-3, 3), 0, random.uniform(-4, 1.5)};
        const double h = random.uniform(0.5, 1.3);
        const Vec3 top = base + Vec3{random.uniform(-0.15, 0.15), h, random.uniform(-0.15, 0.15)};
        stems.append(makeTube({base, lerp(base, top, 0.5) + Vec3{0.04, 0, 0}, top}, 0.008, 5));
        const Mat4 orient = Mat4::translation(top) * Mat4::rotation({0, 1, 0}, random.uniform(0, kPi)) *
                            Mat4::rotation({1, 0, 0}, random.uniform(-1.2, -0.3));
        heads.append(makeQuad(0.35, 0.35), orient);
        // A second leaf-like cross quad lower on the stem.
        heads.append(makeQuad(0.25, 0.25), Mat4::translation(lerp(base, top, 0.45)) *
                                               Mat4::rotation({0, 1, 0}, random.uniform(0, kPi)));
    }
    s.addObject("stems", s.addMesh(std::move(stems)), solid({0.15, 0.45, 0.12}));
    Material petals = solid({1, 1, 1});
    petals.pattern = Pattern::Texture, petals.texture = 0, petals.alphaCutout = true;
    s.addObject("flowers", s.addMesh(std::move(heads)), petals);
    s.camera = fixedCamera({0, 1.5, 3.6}, {0, 0.6, -1}, 55);
}

void hardEdgesScene(Scene& s, const SceneOptions&) {
    s.background = {0.75, 0.85, 0.95};
    // A building front far away: a wall with rows of small dark windows and white frames.
    s.addObject("facade", s.addMesh(makeQuad(30, 14)), solid({0.78, 0.7, 0.6}), [](double) {
        return Mat4::translation({0, 5, -25});
    });
    const int window = s.addMesh(makeBox({0.7, 1.0, 0.05})), frame = s.addMesh(makeBox({0.85, 1.15, 0.02}));
    for (int row = 0; row < 5; ++row)
        for (int column = -8; column <= 8; ++column) {
            const Vec3 at{column * 1.6, 0.5 + row * 2.3, -24.9};
            s.addObject("window", window, solid({0.1, 0.12, 0.18}, true, 0.6), [at](double) {
                return Mat4::translation(at + Vec3{0, 0, 0.04});
            });
            s.addObject("frame", frame, solid({0.95, 0.95, 0.95}),
                        [at](double) { return Mat4::translation(at); });
        }
    // Near: a garden wall and a pipe along it.
    s.addObject("wall", s.addMesh(makeBox({12, 1.2, 0.3})), solid({0.55, 0.5, 0.48}), [](double) {
        return Mat4::translation({0, 0.6, -3});
    });
    s.addObject("pipe", s.addMesh(makeTube({{-6, 1.35, -2.95}, {6, 1.35, -2.95}}, 0.08, 16)),
                solid({0.45, 0.26, 0.12}, true, 0.3));
    s.addObject("ground", s.addMesh(floorMesh(80)), solid({0.35, 0.4, 0.3}));
    s.camera = fixedCamera({0.5, 1.6, 3}, {0, 2.8, -20}, 55);
}

void planesScene(Scene& s, const SceneOptions& o) {
    s.textures.push_back(makeTexture(o.texture, 512, o.seed));
    s.sampler = o.sampler;
    Material m = solid({1, 1, 1}, false);
    m.pattern = Pattern::Texture, m.texture = 0;
    // A floor receding to the horizon and a wall at a grazing angle, both tiled many times.
    Mesh floor;
    floor.append(makeQuad(40, 200, 20, 100), Mat4::rotation({1, 0, 0}, -kPi / 2));
    s.addObject("floor", s.addMesh(std::move(floor)), m, [](double) {
        return Mat4::translation({0, 0, -95});
    });
    Mesh wall;
    wall.append(makeQuad(200, 12, 100, 6), Mat4::rotation({0, 1, 0}, kPi / 2));
    s.addObject("wall", s.addMesh(std::move(wall)), m, [](double) {
        return Mat4::translation({-6, 6, -95});
    });
    s.camera = fixedCamera({0, 1.2, 4}, {0.5, 0.6, -10}, 60);
}

void sweepScene(Scene& s, const SceneOptions&, Pattern pattern) {
    Material m = solid({1, 1, 1}, false);
    m.pattern = pattern;
    m.frequency = pattern == Pattern::Sweep ? 160.0 : 900.0;
    s.addObject(pattern == Pattern::Sweep ? "sweep" : "zone plate", s.addMesh(makeQuad(4, 4)), m, [](double) {
        return Mat4::rotation({1, 0, 0}, -0.5);
    });
    s.camera = fixedCamera({0, 0, 4.2}, {0, 0, 0}, 50);
}

void lineFanScene(Scene& s, const SceneOptions&) {
    // A wheel of thin spokes turning 7 degrees per frame: wagon-wheel aliasing in motion.
    s.background = {0.95, 0.95, 0.95};
    Mesh spokes;
    for (int i = 0; i < 90; ++i)
        spokes.append(makeBox({1.8, 0.006, 0.002}),
                      Mat4::rotation({0, 0, 1}, 2 * kPi * i / 90) * Mat4::translation({0.9, 0, 0}));
    spokes.append(makeTube(arc({0, 0, 0}, 1.8, 0, 2 * kPi, 128), 0.01, 6));
    s.addObject("wheel", s.addMesh(std::move(spokes)), solid({0.05, 0.05, 0.05}, false), [](double t) {
        return Mat4::rotation({0, 0, 1}, 7.0 * kPi / 180.0 * t);
    });
    s.camera = fixedCamera({0, 0, 4.5}, {0, 0, 0}, 50);
}

void normalMapScene(Scene& s, const SceneOptions& o) {
    Material shiny = solid({0.55, 0.57, 0.6}, true, 1.0);
    shiny.pattern = Pattern::Bumps, shiny.shininess = 200, shiny.frequency = 12;
    if (o.bump != Bump::Procedural) {
        s.normalMaps.push_back(makeNormalMap("dimples", 256, o.seed));
        s.sampler = o.sampler;  // how the standard chain is read
        shiny.normalMap = 0;
    }
    Mesh floor;
    floor.append(makeQuad(12, 12, 6, 6), Mat4::rotation({1, 0, 0}, -kPi / 2));
    s.addObject("plate", s.addMesh(std::move(floor)), shiny);
    s.addObject("sphere", s.addMesh(makeSphere(0.8, 96, 48)), shiny, [](double) {
        return Mat4::translation({0.8, 0.8, -1});
    });
    s.lightDirection = {0.2, 0.5, -0.8};  // behind the objects: grazing highlights
    s.camera = fixedCamera({0, 1.6, 3.5}, {0, 0.2, -1}, 55);
}

// The random composer: a few objects drawn from every family's vocabulary, random colours, light and a
// camera path (a slow orbit, so sequences have motion).
void randomScene(Scene& s, const SceneOptions& o) {
    Random random(o.seed);
    s.background = random.colour();
    s.lightDirection = normalize({random.uniform(-1, 1), random.uniform(0.3, 1), random.uniform(-1, 1)});
    const std::vector<std::string> textures = {"checker", "bricks", "stripes", "text", "noise"};
    s.textures.push_back(makeTexture(textures[size_t(random.below(5))], 512, o.seed));
    s.sampler = Sampler(random.below(3));  // not aniso16: llvmpipe makes it very slow on grazing planes
    Material ground = solid(random.colour());
    if (random.below(2) == 0)
        ground.pattern = Pattern::Texture, ground.texture = 0, ground.colour = {1, 1, 1};
    Mesh floor;
    floor.append(makeQuad(60, 60, 30, 30), Mat4::rotation({1, 0, 0}, -kPi / 2));
    s.addObject("ground", s.addMesh(std::move(floor)), ground);
    const int count = 3 + random.below(6);
    for (int i = 0; i < count; ++i) {
        Material m = solid(random.colour(), random.below(5) != 0, random.uniform(0, 0.8));
        m.shininess = random.uniform(8, 128);
        Mesh mesh;
        switch (random.below(6)) {
            case 0:
                mesh = makeSphere(random.uniform(0.3, 1.0), 64, 32);
                break;
            case 1:
                mesh = makeBox({random.uniform(0.2, 2), random.uniform(0.2, 2), random.uniform(0.2, 2)});
                break;
            case 2: {
                std::vector<Vec3> path;
                Vec3 p{0, 0, 0}, d = random.unitVector();
                for (int k = 0; k < 20; ++k) {
                    d = normalize(d + random.unitVector() * 0.4);
                    p = p + d * 0.15;
                    path.push_back(p);
                }
                mesh = makeTube(path, random.uniform(0.01, 0.15), 16);
                break;
            }
            case 3:
                mesh = hairballMesh(random.next(), 300);
                break;
            case 4: {  // a grille of thin bars
                const double gap = random.uniform(0.03, 0.12);
                for (int k = 0; k < 20; ++k)
                    mesh.append(makeBox({0.015, 1.5, 0.015}), Mat4::translation({(k - 10) * gap, 0, 0}));
                break;
            }
            default:
                mesh = makeQuad(random.uniform(0.5, 2), random.uniform(0.5, 2), 2, 2);
                m.pattern = Pattern::Texture, m.texture = 0, m.colour = {1, 1, 1};
                break;
        }
        const Vec3 at{random.uniform(-2.5, 2.5), random.uniform(0.3, 1.8), random.uniform(-3, 1)};
        const Vec3 axis = random.unitVector();
        const double angle = random.uniform(0, 2 * kPi), spin = random.uniform(-1.5, 1.5) * kPi / 180.0;
        s.addObject("object", s.addMesh(std::move(mesh)), m,
                    [=](double t) { return Mat4::translation(at) * Mat4::rotation(axis, angle + spin * t); });
    }
    const double radius = random.uniform(4, 7), height = random.uniform(0.8, 3),
                 phase = random.uniform(0, 2 * kPi);
    const double speed = random.uniform(-0.4, 0.4) * kPi / 180.0, fov = random.uniform(40, 65);
    s.camera = [=](double t) {
        const double a = phase + speed * t;
        return CameraPose{{radius * std::sin(a), height, radius * std::cos(a) - 1},
                          {0, 0.8, -1},
                          {0, 1, 0},
                          fov * kPi / 180.0};
    };
}

struct Entry {
    SceneInfo info;
    std::function<void(Scene&, const SceneOptions&)> build;
};

const std::vector<Entry>& entries() {
    static const std::vector<Entry> list = {
        {{"sphere", "a lit red sphere on a floor", "shapes"}, sphereScene},
        {{"corridor", "a sphere moving through a corridor (100 frames; ghosting test)", "shapes"},
         corridorScene},
        {{"text-wall", "white wall with black letters", "text"}, textWallScene},
        {{"pipe", "brown bent pipe in front of a wall (--camera tilted for the tilted view)", "pipes"},
         pipeScene},
        {{"blinds", "window with closed blinds: pixel-wide gaps", "thin"}, blindsScene},
        {{"arched-window", "arched window with glazing bars", "thin"}, archedWindowScene},
        {{"hairball", "2,500 thin strands, flat colour", "hair"},
         [](Scene& s, const SceneOptions& o) { hairballScene(s, o, false, false); }},
        {{"hairball-lit", "2,500 thin shiny strands, lit", "hair"},
         [](Scene& s, const SceneOptions& o) { hairballScene(s, o, true, false); }},
        {{"hairball-rotating", "the flat hairball turning 1.2 degrees per frame (ghosting test)", "hair"},
         [](Scene& s, const SceneOptions& o) { hairballScene(s, o, false, true); }},
        {{"hairball-lit-rotating", "the lit hairball turning 1.2 degrees per frame (ghosting test)", "hair"},
         [](Scene& s, const SceneOptions& o) { hairballScene(s, o, true, true); }},
        {{"atrium", "a courtyard of columns and arches with a sphere in the middle", "architecture"},
         atriumScene},
        {{"flowers", "alpha-cutout flowers on stems", "foliage"}, flowersScene},
        {{"hard-edges", "a facade of windows far away, a wall and a pipe near", "architecture"},
         hardEdgesScene},
        {{"planes", "receding textured planes (--texture, --sampler)", "textures"}, planesScene},
        {{"sweep", "product-of-cosines frequency sweep", "procedural"},
         [](Scene& s, const SceneOptions& o) { sweepScene(s, o, Pattern::Sweep); }},
        {{"zone-plate", "zone plate cos(k r^2)", "procedural"},
         [](Scene& s, const SceneOptions& o) { sweepScene(s, o, Pattern::ZonePlate); }},
        {{"line-fan", "a turning wheel of thin spokes (wagon-wheel aliasing)", "procedural"}, lineFanScene},
        {{"normal-map", "shiny normal-mapped plate and sphere (shading aliasing)", "shading"},
         normalMapScene},
        {{"random", "random composition from --seed: shapes, hair, grilles, textures, an orbiting camera",
          "random"},
         randomScene},
        {{"vector-art", "flat 2D drawing: lines, fans, polygons, curves, rings, hatching, roads (--seed)",
          "vector"},
         vectorArtScene},
        {{"type", "lines of text in 20 fonts from 4 to 48 pixels, over panels (--seed)", "type"}, typeScene},
    };
    return list;
}

}  // namespace

const char* samplerName(Sampler sampler) {
    switch (sampler) {
        case Sampler::Point:
            return "point";
        case Sampler::Bilinear:
            return "bilinear";
        case Sampler::Trilinear:
            return "trilinear";
        case Sampler::Anisotropic16:
            return "aniso16";
        case Sampler::Fourier:
            return "fourier";
    }
    return "?";
}

Sampler parseSampler(const std::string& name) {
    for (Sampler s :
         {Sampler::Point, Sampler::Bilinear, Sampler::Trilinear, Sampler::Anisotropic16, Sampler::Fourier})
        if (name == samplerName(s)) return s;
    throw Error("unknown sampler '" + name + "' (point, bilinear, trilinear, aniso16, fourier)");
}

const char* bumpName(Bump bump) {
    switch (bump) {
        case Bump::Procedural:
            return "procedural";
        case Bump::Standard:
            return "standard";
        case Bump::Super:
            return "super";
    }
    return "?";
}

Bump parseBump(const std::string& name) {
    for (Bump b : {Bump::Procedural, Bump::Standard, Bump::Super})
        if (name == bumpName(b)) return b;
    throw Error("unknown bump mode '" + name + "' (procedural, standard, super)");
}

SceneObject& Scene::addObject(const std::string& objectName, int mesh, const Material& material,
                              std::function<Mat4(double)> transform) {
    SceneObject object;
    object.name = objectName, object.mesh = mesh, object.material = material;
    object.id = uint32_t(objects.size() + 1);
    object.transform = std::move(transform);
    objects.push_back(std::move(object));
    return objects.back();
}

size_t Scene::triangleCount() const {
    size_t n = 0;
    for (const SceneObject& o : objects) n += meshes[size_t(o.mesh)].triangleCount();
    return n;
}

const std::vector<SceneInfo>& sceneCatalogue() {
    static const std::vector<SceneInfo> infos = [] {
        std::vector<SceneInfo> v;
        for (const Entry& e : entries()) v.push_back(e.info);
        return v;
    }();
    return infos;
}

Scene buildScene(const std::string& name, const SceneOptions& options) {
    for (const Entry& e : entries()) {
        if (e.info.name != name) continue;
        Scene scene;
        scene.name = name;
        scene.fourier = options.fourier;
        scene.bump = options.bump;
        if (options.bumpLobes < 1 || options.bumpLobes > 4)
            throw Error("super bump mapping keeps 1 to 4 lobes a texel, not " +
                        std::to_string(options.bumpLobes));
        scene.bumpLobes = options.bumpLobes;
        e.build(scene, options);
        if (options.tiltedCamera) scene.camera = tilt(scene.camera);
        return scene;
    }
    std::string names;
    for (const Entry& e : entries()) names += (names.empty() ? "" : ", ") + e.info.name;
    throw Error("unknown scene '" + name + "' (" + names + ")");
}

TextureImage makeTexture(const std::string& kind, int size, uint64_t seed) {
    cv::Mat image(size, size, CV_8UC4, cv::Scalar(255, 255, 255, 255));
    Random random(seed ^ 0x7E7ull);
    if (kind == "checker") {
        const int cell = size / 8;
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x)
                if (((x / cell) + (y / cell)) % 2) image.at<cv::Vec4b>(y, x) = {20, 20, 20, 255};
    } else if (kind == "bricks") {
        image.setTo(cv::Scalar(200, 200, 200, 255));  // mortar
        const int rows = 8, h = size / rows, w = size / 4;
        for (int r = 0; r < rows; ++r)
            for (int c = -1; c < 5; ++c) {
                const int x0 = c * w + (r % 2) * w / 2;
                const int shade = 140 + random.below(60);
                cv::rectangle(image, cv::Rect(x0 + 3, r * h + 3, w - 6, h - 6),
                              cv::Scalar(40, 60 + shade / 4, shade, 255), cv::FILLED);
            }
    } else if (kind == "stripes") {
        const int period = size / 16;
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x)
                if ((x % period) < period / 2) image.at<cv::Vec4b>(y, x) = {0, 0, 0, 255};
    } else if (kind == "text") {
        const char* lines[] = {"The quick brown fox", "jumps over the lazy", "dog. SPHINX OF BLACK",
                               "QUARTZ, JUDGE MY",    "VOW 0123456789",      "aliasing steps &",
                               "crawling edges #%@"};
        const double scale = size / 520.0;
        for (int i = 0; i < 14; ++i)
            cv::putText(image, lines[i % 7], cv::Point(int(10 * scale), int((34 + i * 36) * scale)),
                        cv::FONT_HERSHEY_SIMPLEX, 1.0 * scale, cv::Scalar(0, 0, 0, 255),
                        std::max(1, int(2 * scale)), cv::LINE_8);
    } else if (kind == "noise") {
        // Value noise of a few octaves: a texture with energy at every frequency.
        std::vector<double> lattice(64 * 64);
        for (double& v : lattice) v = random.uniform();
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x) {
                double value = 0, amplitude = 0.5;
                for (int octave = 0; octave < 5; ++octave) {
                    const double cells = 4 << octave;
                    const double fx = x * cells / size, fy = y * cells / size;
                    const int ix = int(fx), iy = int(fy);
                    const double tx = fx - ix, ty = fy - iy;
                    auto at = [&](int i, int j) {
                        return lattice[size_t(((j & 63) * 64) + (i & 63) + octave * 7) % lattice.size()];
                    };
                    const double v = (1 - ty) * ((1 - tx) * at(ix, iy) + tx * at(ix + 1, iy)) +
                                     ty * ((1 - tx) * at(ix, iy + 1) + tx * at(ix + 1, iy + 1));
                    value += amplitude * v, amplitude *= 0.5;
                }
                const uint8_t g = uint8_t(std::clamp(value * 255 / 0.97, 0.0, 255.0));
                image.at<cv::Vec4b>(y, x) = {g, g, g, 255};
            }
    } else if (kind == "flower") {
        // Petals around a centre; alpha 0 outside (cut out by the shader).
        image.setTo(cv::Scalar(0, 0, 0, 0));
        const cv::Point c(size / 2, size / 2);
        const cv::Scalar petal(60 + random.below(80), 80 + random.below(60), 230, 255);
        for (int i = 0; i < 6; ++i) {
            const double a = i * 60.0;
            cv::ellipse(image,
                        c + cv::Point(int(size * 0.22 * std::cos(a * kPi / 180)),
                                      int(size * 0.22 * std::sin(a * kPi / 180))),
                        cv::Size(size / 5, size / 10), a, 0, 360, petal, cv::FILLED, cv::LINE_8);
        }
        cv::circle(image, c, size / 10, cv::Scalar(30, 200, 250, 255), cv::FILLED, cv::LINE_8);
    } else {
        throw Error("unknown texture '" + kind + "' (checker, bricks, stripes, text, noise)");
    }
    TextureImage t;
    t.name = kind, t.width = size, t.height = size;
    t.rgba.resize(size_t(size) * size_t(size) * 4);
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const cv::Vec4b p = image.at<cv::Vec4b>(y, x);  // OpenCV is BGRA
            uint8_t* q = &t.rgba[(size_t(y) * size_t(size) + size_t(x)) * 4];
            q[0] = p[2], q[1] = p[1], q[2] = p[0], q[3] = p[3];
        }
    return t;
}

}  // namespace dejag::render
