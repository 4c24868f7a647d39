#version 430
out float visible;
void main() { visible = 1.0; }
