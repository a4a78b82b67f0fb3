// A helper with a mistake: its diagnostic is reported inside this file, after an include note.
float helper(float a) { return a * Kn; }
