# visibility_pareto_guitar.png from visibility_pareto_guitar.csv (written by fillgs); re-plot with: gnuplot visibility_pareto_guitar.gp
set terminal pngcairo size 960,600 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'visibility_pareto_guitar.png'
set title 'visibility: time against visible-set recall (vs exact)'
set xlabel 'time (s, log scale)'
set ylabel 'recall'
set lmargin at screen 0.09
set rmargin at screen 0.74
set bmargin at screen 0.12
set tmargin at screen 0.9
set key outside right top vertical Left reverse noautotitle
set grid xtics ytics lc rgb '#dddddd' lt 1
set logscale x 10
set format x '%g'
set xrange [0.0343231016:35.0838751]
set yrange [0.422884041:1.04274933]
set label "frustum" at 0.054374399, 1 left font ',9' tc rgb '#3c78b4'
set label "exact" at 0.603654968, 1 left font ',9' tc rgb '#3c78b4'
set label "raytraced s8" at 1.91190803, 0.465633372 left font ',9' tc rgb '#3c78b4'
set label "raytraced s4 plain 3D" at 2.95295987, 0.65073931 left font ',9' tc rgb '#3c78b4'
set label "raytraced s4" at 6.86204961, 0.778693943 left font ',9' tc rgb '#3c78b4'
set label "raytraced s2" at 9.19013611, 0.951776085 left font ',9' tc rgb '#3c78b4'
plot 'visibility_pareto_guitar.csv' skip 1 using 2:($1 == 0 ? $3 : NaN) with points pt 7 ps 1.1 lw 1.5 lc rgb '#3c78b4' title 'guitar 1352x1014'
