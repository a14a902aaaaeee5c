// POV-Ray twin of bench/csg.toml for bench/equal_work.py: the same camera,
// objects, materials and light, as bench/whitted.pov and bench/solids.pov
// map them. POV-Ray is left-handed, so z is negated: points and normals get
// -z, and a rotation about the x or y axis turns the other way (about z it
// does not). A plane { n, d } is the same half-space n.p < d in both. The
// texture or material after a CSG's parts goes to the parts that have none
// (Prism: the CSG's material); the transformations after the parts are the
// CSG's transform.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 8 adc_bailout 0.001 ambient_light rgb <0.15, 0.15, 0.15> }
background { rgb <0.25, 0.45, 0.85> }
camera {
  perspective
  location <0, 2.5, -8>
  look_at <0, 1, 0>
  right x*4/3
  angle 51.78  // horizontal: our 40° vertical at 4:3
}
light_source {
  <4, 9, -7> color rgb 1
  // The sphere light of radius 0.5 with 16 samples: a 4×4 circular area light.
  area_light <1, 0, 0>, <0, 0, 1>, 4, 4 circular orient
}

#declare Mirror = texture {
  pigment { color rgb <0.8, 0.8, 0.85> }
  finish { ambient 0.1 diffuse 0.15 phong 0.8 phong_size 80 reflection 0.75 }
}
#declare Glass = material {
  texture {
    pigment { color rgbt <1, 1, 1, 0.9> }
    finish { ambient 0 diffuse 0 phong 0.8 phong_size 120 reflection 0.1 }
  }
  interior { ior 1.5 }
}
#macro Plain(C)
  texture {
    pigment { color rgb C }
    finish { ambient 0.3 diffuse 0.7 phong 0.3 phong_size 30 }
  }
#end
#declare Ivory = Plain(<0.95, 0.92, 0.85>)
#declare Pip = Plain(<0.1, 0.1, 0.12>)
#declare Red = Plain(<0.85, 0.15, 0.1>)
#declare Blue = Plain(<0.15, 0.3, 0.85>)
#declare Green = Plain(<0.15, 0.7, 0.25>)
#declare Gold = Plain(<0.9, 0.7, 0.2>)

// The floor: a slab, its top at y = 0.
box {
  <-8, -0.3, 12>, <8, 0, -5>
  pigment { checker color rgb <0.9, 0.9, 0.88> color rgb <0.25, 0.25, 0.3> }
  finish { ambient 0.4 diffuse 0.7 phong 0.2 phong_size 20 }
}

// Back row. A mirror wall with a round hole through it (the bore a mirror too).
difference {  // mirror wall with a round hole
  box { <-1.8, 0, 0.12>, <1.8, 2.8, -0.12> }
  cylinder { <0.7, 1.7, 0.5>, <0.7, 1.7, -0.5>, 0.6 }
  texture { Mirror }
  rotate -12*y translate <-0.3, 0.01, 5>
}

// A mirror ball drilled through twice, the bores gold.
difference {  // drilled mirror ball
  sphere { <0, 0, 0>, 0.85 }
  cylinder { <-1.2, 0, 0>, <1.2, 0, 0>, 0.36 texture { Gold } }
  cylinder { <0, 0, 1.2>, <0, 0, -1.2>, 0.26 texture { Gold } }
  texture { Mirror }
  rotate 30*y translate <-3, 0.86, 3>
}

// A column cut by a tilted plane: the half-space n.p < d (unit normal).
intersection {  // cut column
  cylinder { <0, 0, 0>, <0, 2, 0>, 0.4 }
  plane { <0.48, 0.8, -0.36>, 1.12 }
  texture { Blue }
  translate <-0.9, 0.01, 3.4>
}

// Three overlapping glass spheres merged: no inner surfaces.
merge {  // glass cluster
  sphere { <-0.35, 0.5, -0.1>, 0.5 }
  sphere { <0.35, 0.5, 0.1>, 0.5 }
  sphere { <0, 1.05, 0>, 0.45 }
  material { Glass }
  translate <2.6, 0.01, 3>
}

// Middle row. Dice: a rounded cube (box and sphere) less 21 pips; 0.01 above the floor.
difference {  // ivory die
  intersection { box { <-0.8, -0.8, -0.8>, <0.8, 0.8, 0.8> } sphere { 0, 1.1 } }
  sphere { <0, 0.9, 0>, 0.16 texture { Pip } }
  sphere { <-0.4, -0.9, 0.4>, 0.16 texture { Pip } }
  sphere { <-0.4, -0.9, 0>, 0.16 texture { Pip } }
  sphere { <-0.4, -0.9, -0.4>, 0.16 texture { Pip } }
  sphere { <0.4, -0.9, 0.4>, 0.16 texture { Pip } }
  sphere { <0.4, -0.9, 0>, 0.16 texture { Pip } }
  sphere { <0.4, -0.9, -0.4>, 0.16 texture { Pip } }
  sphere { <-0.4, 0.4, -0.9>, 0.16 texture { Pip } }
  sphere { <0.4, -0.4, -0.9>, 0.16 texture { Pip } }
  sphere { <-0.4, -0.4, 0.9>, 0.16 texture { Pip } }
  sphere { <-0.4, 0.4, 0.9>, 0.16 texture { Pip } }
  sphere { <0, 0, 0.9>, 0.16 texture { Pip } }
  sphere { <0.4, -0.4, 0.9>, 0.16 texture { Pip } }
  sphere { <0.4, 0.4, 0.9>, 0.16 texture { Pip } }
  sphere { <0.9, -0.4, -0.4>, 0.16 texture { Pip } }
  sphere { <0.9, 0, 0>, 0.16 texture { Pip } }
  sphere { <0.9, 0.4, 0.4>, 0.16 texture { Pip } }
  sphere { <-0.9, -0.4, 0.4>, 0.16 texture { Pip } }
  sphere { <-0.9, -0.4, -0.4>, 0.16 texture { Pip } }
  sphere { <-0.9, 0.4, 0.4>, 0.16 texture { Pip } }
  sphere { <-0.9, 0.4, -0.4>, 0.16 texture { Pip } }
  texture { Ivory }
  scale 0.5 rotate -30*y translate <-1.9, 0.41, 1.4>
}

// A red die turned over, ivory pips.
difference {  // red die
  intersection { box { <-0.8, -0.8, -0.8>, <0.8, 0.8, 0.8> } sphere { 0, 1.1 } }
  sphere { <0, 0.9, 0>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.9, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.9, 0>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.9, -0.4>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.9, 0.4>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.9, 0>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.9, -0.4>, 0.16 texture { Ivory } }
  sphere { <-0.4, 0.4, -0.9>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.4, -0.9>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <-0.4, 0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <0, 0, 0.9>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <0.4, 0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <0.9, -0.4, -0.4>, 0.16 texture { Ivory } }
  sphere { <0.9, 0, 0>, 0.16 texture { Ivory } }
  sphere { <0.9, 0.4, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, -0.4, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, -0.4, -0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, 0.4, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, 0.4, -0.4>, 0.16 texture { Ivory } }
  texture { Red }
  scale 0.45 rotate -90*x rotate 50*y translate <-0.6, 0.37, 1.8>
}

// A red ball drilled twice, the bores red.
difference {  // drilled red ball
  sphere { <0, 0, 0>, 0.55 }
  cylinder { <-0.8, 0, 0>, <0.8, 0, 0>, 0.22 }
  cylinder { <0, 0, 0.8>, <0, 0, -0.8>, 0.16 }
  texture { Red }
  rotate -20*x rotate 35*y translate <1.2, 0.56, 1.6>
}

// A biconvex lens standing in front of the red die (0.3 thick, 1.16 across).
intersection {  // upright lens
  sphere { <0, 0, -1.05>, 1.2 }
  sphere { <0, 0, 1.05>, 1.2 }
  material { Glass }
  rotate -20*y translate <0.45, 0.85, 0.3>
}

// Front row. A glass block (0.02 above the floor) with a spherical air bubble inside.
difference {  // glass block with a bubble
  box { <-0.45, 0.02, 0.45>, <0.45, 0.92, -0.45> }
  sphere { <0.05, 0.5, 0>, 0.28 }
  material { Glass }
  rotate -35*y translate <0.9, 0, -1.6>
}

// A larger lens tilted 60 degrees over the floor, which it magnifies.
intersection {  // tilted lens
  sphere { <0, 0, -1.7>, 2 }
  sphere { <0, 0, 1.7>, 2 }
  material { Glass }
  scale 0.6 rotate -60*x translate <-2.5, 0.75, -1.1>
}

// A small green die on its side.
difference {  // green die
  intersection { box { <-0.8, -0.8, -0.8>, <0.8, 0.8, 0.8> } sphere { 0, 1.1 } }
  sphere { <0, 0.9, 0>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.9, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.9, 0>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.9, -0.4>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.9, 0.4>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.9, 0>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.9, -0.4>, 0.16 texture { Ivory } }
  sphere { <-0.4, 0.4, -0.9>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.4, -0.9>, 0.16 texture { Ivory } }
  sphere { <-0.4, -0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <-0.4, 0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <0, 0, 0.9>, 0.16 texture { Ivory } }
  sphere { <0.4, -0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <0.4, 0.4, 0.9>, 0.16 texture { Ivory } }
  sphere { <0.9, -0.4, -0.4>, 0.16 texture { Ivory } }
  sphere { <0.9, 0, 0>, 0.16 texture { Ivory } }
  sphere { <0.9, 0.4, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, -0.4, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, -0.4, -0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, 0.4, 0.4>, 0.16 texture { Ivory } }
  sphere { <-0.9, 0.4, -0.4>, 0.16 texture { Ivory } }
  texture { Green }
  scale 0.35 rotate 90*z rotate 20*y translate <-0.6, 0.29, -1.7>
}

// A bowl: inside a ball, outside (inverse) a smaller one, below a plane.
intersection {  // red bowl
  sphere { <0, 0, 0>, 0.5 }
  sphere { <0, 0, 0>, 0.45 inverse }
  plane { <0, 1, 0>, 0 }
  texture { Red }
  translate <2, 0.51, -2.4>
}

// A mirror dome: a ball above the plane y = 0 (normal down: inside is above).
intersection {  // mirror dome
  sphere { <0, 0, 0>, 0.55 }
  plane { <0, -1, 0>, 0 }
  texture { Mirror }
  translate <2.8, 0.01, -0.8>
}
