#version 450
// Blinn-Phong with a key light, a hemisphere ambient term and a fill from the viewer's side:
// enough shading to read the shape of tissue, cheap enough for a CPU rasterizer. With the field
// lamp on, the light falls off with distance from the viewer past the lamp's focus (an
// operating lamp's pool of light): nearer tissue is brighter, a depth cue in each eye.
#extension GL_EXT_multiview : require

layout(location = 0) in vec3 v_normal;
layout(location = 1) in vec3 v_world;
layout(location = 2) in float v_open;  // ambient occlusion: 1 where the whole sky is open

layout(set = 0, binding = 0) uniform Eyes {
  mat4 view_projection[2];
  vec4 eye_position[2];
  vec4 light_direction;
  vec4 lamp;  // xyz: the field lamp's focus (world mm); w: 1 when the lamp is on
} eyes;

layout(push_constant) uniform Draw {
  mat4 model;
  vec4 colour;
  vec4 material;  // ambient, diffuse, specular, shininess
  vec4 interior;  // rgb: the inner side's colour (back faces of an open solid)
} draw;

layout(location = 0) out vec4 out_colour;

void main() {
  // A back face is the inside of the tissue seen through an incision, and a wound's wall (its
  // vertices' normals 2 + their occlusion long) is the tissue's inside too: the interior colour,
  // no highlight (wet cut tissue reads matte at this scale). A back face's normal turns to the
  // viewer.
  const bool wall = v_open > 1.5;
  const bool back = !gl_FrontFacing;
  const bool inside = back || wall;
  const vec3 n = back ? -normalize(v_normal) : normalize(v_normal);
  const vec3 albedo = inside ? draw.interior.rgb : draw.colour.rgb;
  const float shine = inside ? 0.0 : draw.material.z;
  const vec3 l = normalize(eyes.light_direction.xyz);
  const vec3 v = normalize(eyes.eye_position[gl_ViewIndex].xyz - v_world);
  const vec3 h = normalize(l + v);
  // The ambient term never reaches black: the side away from the key light still gets the
  // light the field scatters back (a third of the sky's).
  // Ambient occlusion dims the sky's light, and part of the key light (the lamp is wide: what
  // hides much of the sky hides much of it too), a soft shadow where parts of the field meet.
  const float open = clamp(wall ? v_open - 2.0 : v_open, 0.0, 1.0);
  const float hemisphere = open * mix(0.35, 1.0, 0.5 + 0.5 * dot(n, l));
  const float diffuse = mix(1.0, open, 0.6) * max(dot(n, l), 0.0);
  const float fill = 0.25 * max(dot(n, v), 0.0);
  const float specular = diffuse > 0.0 ? pow(max(dot(n, h), 0.0), draw.material.w) : 0.0;
  float pool = 1.0;
  if (eyes.lamp.w > 0.0) {
    const vec3 eye = eyes.eye_position[gl_ViewIndex].xyz;
    const float focus = length(eyes.lamp.xyz - eye);
    const float d = max(length(v_world - eye), 1e-3);
    pool = clamp((focus * focus) / (d * d), 0.3, 1.4);
  }
  const vec3 c = pool * (albedo * (draw.material.x * hemisphere +
                                   draw.material.y * (diffuse + fill)) +
                         vec3(shine * specular));
  out_colour = vec4(pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
