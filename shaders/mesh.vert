#version 450
// Solids and instruments, both eyes in one multiview pass: gl_ViewIndex picks the eye.
#extension GL_EXT_multiview : require

layout(location = 0) in vec3 in_position;  // world millimetres (solids) or model space
layout(location = 1) in vec3 in_normal;  // its length: ambient occlusion (1 open), + 2 on a wall

layout(set = 0, binding = 0) uniform Eyes {
  mat4 view_projection[2];
  vec4 eye_position[2];  // world millimetres
  vec4 light_direction;  // towards the light, world frame
  vec4 lamp;             // the field lamp (fragment stage)
} eyes;

layout(push_constant) uniform Draw {
  mat4 model;      // identity for solids; the instrument's pose otherwise (rigid)
  vec4 colour;     // linear RGB, alpha unused
  vec4 material;   // ambient, diffuse, specular, shininess
  vec4 interior;   // the inner side's colour (fragment stage)
} draw;

layout(location = 0) out vec3 v_normal;
layout(location = 1) out vec3 v_world;
layout(location = 2) out float v_open;

void main() {
  const vec4 world = draw.model * vec4(in_position, 1.0);
  v_world = world.xyz;
  v_normal = mat3(draw.model) * in_normal;
  v_open = length(in_normal);
  gl_Position = eyes.view_projection[gl_ViewIndex] * world;
}
