//! Files for mimic: OBJ meshes, layouts and rigs.
