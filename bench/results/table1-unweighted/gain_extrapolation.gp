# gain_extrapolation.png from gain_extrapolation.csv (written by fillgs); re-plot with: gnuplot gain_extrapolation.gp
set terminal pngcairo size 640,480 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'gain_extrapolation.png'
set title 'extrapolation: gain over the control per strategy and refiner (n3v)'
set xlabel ''
set ylabel 'PSNR gain (dB)'
set key off
set xtics rotate by -45 left scale 0 ('fillgs@oracle' 0, 'random@oracle' 1, 'negative@oracle' 2, 'interpolation@oracle' 3, 'fisherrf@oracle' 4, 'coverage3d@oracle' 5, 'coverage4d@oracle' 6)
set xrange [-0.6:6.6]
set yrange [*<0:*]
set offsets 0, 0, graph 0.08, 0
set boxwidth 0.7
plot 'gain_extrapolation.csv' skip 1 using 0:2 with boxes lc rgb '#3c78b4', '' skip 1 using 0:2:3 with labels offset 0,0.7 font ',9'
